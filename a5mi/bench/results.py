"""One scene's benchmark results (the rows of ``a5mi bench``'s table and JSON): kept apart from the runner
(:mod:`a5mi.bench`) and the report (:mod:`a5mi.bench.report`), which both use it."""

from __future__ import annotations

from dataclasses import asdict, dataclass, field
from typing import Any

from a5mi.bench.floor import InProcess
from a5mi.bench.process import ProcessRun


@dataclass
class SceneResult:
    name: str
    path: str
    cold: ProcessRun | None = None
    warm: ProcessRun | None = None
    verbose: ProcessRun | None = None  # best warm ``a5 -v`` run: the process's own stage times
    inproc: InProcess | None = None
    stock: dict[str, float] = field(default_factory=dict)
    a5soln: float | None = None  # measured here
    a5soln_published: float | None = None
    busy_before: float | None = None  # CPU fraction used by others just before this scene's runs
    errors: list[str] = field(default_factory=list)

    def to_json(self) -> dict[str, Any]:
        d = asdict(self)
        for key in ("cold", "warm", "verbose"):
            if d[key] is not None:
                d[key].pop("stderr")
                d[key]["startup"] = getattr(self, key).startup
        if self.inproc is not None:
            d["inproc"]["floor_total"] = self.inproc.floor_total
            d["inproc"]["floor_first_hits_total"] = self.inproc.floor_first_hits_total
        return d
