"""What a build says about each asset: its status and its report (the manifest entry)."""

from __future__ import annotations

from dataclasses import dataclass, field
from enum import StrEnum


class AssetStatus(StrEnum):
    """Where an asset stands in a build (its manifest ``status``)."""

    PENDING = "pending"
    BUILT = "built"
    FAILED = "failed"


@dataclass
class AssetReport:
    """What happened to one asset; ``entry()`` is its manifest entry."""

    name: str
    index: int
    status: AssetStatus = AssetStatus.PENDING
    cached: bool = False
    error: str | None = None
    warnings: list[str] = field(default_factory=list)
    timings_s: dict[str, float] = field(default_factory=dict)
    inputs: dict = field(default_factory=dict)
    outputs: dict[str, dict] = field(default_factory=dict)
    info: dict = field(default_factory=dict)
    traceback: str | None = None

    def entry(self) -> dict:
        """The manifest entry (plain JSON); a cached asset's is the one recorded when it was built."""
        entry = {"name": self.name, "status": self.status.value, "inputs": self.inputs, "outputs": self.outputs,
                 **self.info, "warnings": self.warnings, "timings_s": self.timings_s}
        if self.error:
            entry["error"] = self.error
        return entry

    @classmethod
    def from_entry(cls, index: int, entry: dict) -> "AssetReport":
        known = {"name", "status", "inputs", "outputs", "warnings", "timings_s", "error"}
        return cls(name=entry["name"], index=index, status=AssetStatus(entry["status"]), cached=True,
                   error=entry.get("error"), warnings=list(entry.get("warnings", [])),
                   timings_s=dict(entry.get("timings_s", {})), inputs=entry.get("inputs", {}),
                   outputs=entry.get("outputs", {}), info={k: v for k, v in entry.items() if k not in known})
