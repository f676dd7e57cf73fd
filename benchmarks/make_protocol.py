"""Write the evaluation protocol ``evaluation/protocols/things_v1.{json,npz}`` (deterministic; see evaluation/protocol.py).

Run from the repository root::

    python benchmarks/make_protocol.py [--name things_v1] [--set things]

Needs the text and CAD sources (build123d) and the style set (built and
cached on first use, ~1 minute). The same set and code give the same bytes, so
``git diff`` shows whether a regeneration changed anything.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from core.errors import DecollageError  # noqa: E402
from evaluation.protocol import PROTOCOL_DIR, load_protocol, make_protocol  # noqa: E402


def main(argv: list[str]) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--name", default="things_v1", help="protocol name; reads <name>_contents.yaml")
    ap.add_argument("--set", default="things", help="style set whose exemplars give the styles")
    ap.add_argument("--folder", type=Path, default=PROTOCOL_DIR)
    args = ap.parse_args(argv)
    started = time.perf_counter()
    try:
        path = make_protocol(args.name, args.set, args.folder, progress=lambda n: print(f"  voxelized {n}",
                                                                                        file=sys.stderr))
        protocol = load_protocol(path)
    except DecollageError as exc:
        print(f"error: {exc.one_line()}", file=sys.stderr)
        return 2
    sizes = ", ".join(f"{c}: {'×'.join(map(str, a.shape))}" for c, a in protocol.contents.items())
    print(f"wrote {path} and {protocol.meta['contents_file']}: {len(protocol.contents)} contents × "
          f"{len(protocol.outputs) // max(1, len(protocol.contents))} style assignments = "
          f"{len(protocol.outputs)} outputs ({time.perf_counter() - started:.1f} s)\n{sizes}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
