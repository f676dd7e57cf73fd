"""stylesets.readers.file_cache: one read per file version."""

import os

import pytest

from stylesets.readers.file_cache import cached_per_file


def test_reads_once_per_file_version_and_again_after_a_change(tmp_path):
    calls = []

    @cached_per_file(maxsize=4)
    def read(path, suffix):
        calls.append((path, suffix))
        return path.read_text() + suffix

    f = tmp_path / "a.txt"
    f.write_text("one")
    assert read(f, "!") == "one!"
    assert read(str(f), "!") == "one!"  # same file by another spelling: cached
    assert len(calls) == 1
    assert read(f, "?") == "one?"  # other arguments: another entry
    assert len(calls) == 2
    f.write_text("two!")
    st = f.stat()
    os.utime(f, ns=(st.st_atime_ns, st.st_mtime_ns + 10**9))  # a change the clock's resolution cannot hide
    assert read(f, "!") == "two!!"
    assert len(calls) == 3


def test_a_missing_file_raises_oserror(tmp_path):
    @cached_per_file(maxsize=1)
    def read(path):
        return path.read_text()

    with pytest.raises(OSError):
        read(tmp_path / "missing.txt")
