"""The benchmark's Markdown tables and the machine they were measured on."""

from __future__ import annotations

import os
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

from a5mi.bench.scenes import RAY_KINDS, STAGES, VERBOSE_STAGES

if TYPE_CHECKING:
    from a5mi.bench.results import SceneResult


def format_table(headers: Sequence[str], rows: Sequence[Sequence[Any]]) -> str:
    """A markdown table, columns padded to their widest cell; floats with 3 significant-ish decimals."""

    def cell(v: Any) -> str:
        if v is None:
            return "-"
        if isinstance(v, float):
            return f"{v:.3f}" if abs(v) < 10 else f"{v:.1f}" if abs(v) < 1000 else f"{v:.0f}"
        return str(v)

    table = [[cell(h) for h in headers]] + [[cell(v) for v in r] for r in rows]
    widths = [max(len(r[c]) for r in table) for c in range(len(headers))]
    lines = ["| " + " | ".join(c.ljust(w) if i == 0 else c.rjust(w)
                               for i, (c, w) in enumerate(zip(r, widths, strict=True))) + " |" for r in table]
    lines.insert(1, "|" + "|".join("-" * (w + 2) if i == 0 else "-" * (w + 1) + ":" for i, w in enumerate(widths))
                 + "|")
    return "\n".join(lines)



def machine_info() -> dict[str, Any]:
    """CPU model, logical cores, LLVM library, Mitsuba / Dr.Jit versions (what BENCHMARKS.md quotes)."""
    cpu = "unknown"
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    info: dict[str, Any] = {"cpu": cpu, "cores": os.cpu_count(), "python": sys.version.split()[0]}
    try:
        from a5mi.runtime import llvm

        lib = llvm.check()
        info["llvm"] = f"{lib.major} ({lib.path})"
    except Exception as exc:  # noqa: BLE001
        info["llvm"] = f"unavailable: {exc}"
    try:
        import drjit as dr
        import mitsuba as mi

        info["mitsuba"], info["drjit"] = mi.__version__, dr.__version__
    except Exception:  # noqa: BLE001
        pass
    return info


def _ratio(a: float | None, b: float | None) -> float | None:
    return a / b if a is not None and b else None


def _batch_tables(extra: dict[str, Any]) -> list[str]:
    """The batch figures of :mod:`a5mi.bench.batch`, when measured."""
    from a5mi.bench.batch import TARGET_BATCH_RATIO

    out: list[str] = []
    if extra.get("batch"):
        rows = [[b.name, b.first, len(b.extra), b.median("wall"), b.median("kernel"), b.median("filter"),
                 b.median("write"), b.median("trace_etc"), b.base, b.ratio, f"{b.recompiled}/{len(b.extra)}"]
                for b in extra["batch"]]
        out += [f"Batch renders in one session (in-process, each render written; medians of the extra renders, s; "
                f"ratio = wall / (kernel + filter + write), target <= {TARGET_BATCH_RATIO}; `other` = render - "
                "kernel - filter: Python trace, jitter, camera rays, copies)", "",
                format_table(["scene", "first", "extra", "wall", "kernel", "filter", "write", "other",
                              "kernel+filter+write", "ratio", "recompiled"], rows), ""]
    bp = extra.get("batch_process")
    if bp:
        separate = [w for w in bp["separate_warm"] if w is not None]
        total = sum(separate) if len(separate) == len(bp["separate_warm"]) else None
        out += [f"Batch process: `{bp['cmd']}`: cold {bp['cold'].wall:.3f} s, warm {bp['warm'].wall:.3f} s "
                f"(peak {bp['warm'].peak_mb:.0f} MB, exit {bp['warm'].returncode}) for {len(bp['scenes'])} scenes"
                + (f"; separate warm a5 processes {total:.3f} s in all ({total / bp['warm'].wall:.2f}x)"
                   if total else ""), ""]
    return out


def report(results: Sequence[SceneResult], info: dict[str, Any], extra: dict[str, Any]) -> str:
    """The markdown tables of a run."""
    out = [f"machine: {info.get('cpu')}, {info.get('cores')} logical cores, LLVM {info.get('llvm')}, "
           f"Mitsuba {info.get('mitsuba')}, Dr.Jit {info.get('drjit')}", ""]
    rows = []
    for r in results:
        rows.append([r.name,
                     r.cold.wall if r.cold else None, r.warm.wall if r.warm else None,
                     r.cold.peak_mb if r.cold else None, r.warm.peak_mb if r.warm else None,
                     r.a5soln if r.a5soln is not None else r.a5soln_published,
                     "measured" if r.a5soln is not None else ("published" if r.a5soln_published else None),
                     _ratio(r.a5soln if r.a5soln is not None else r.a5soln_published, r.warm.wall if r.warm else None),
                     r.busy_before])
    out += ["Whole process (`a5 -input SCENE -output OUT.png " + " ".join(extra.get("flags", [])) + "`, wall s, "
            "warm = best of the warm runs; peak RSS MB; busy = CPU share used by other processes just before)", "",
            format_table(["scene", "cold s", "warm s", "cold MB", "warm MB", "a5soln s", "a5soln", "a5soln/warm",
                          "busy"],
                         rows), ""]
    rows = [[r.name, r.verbose.wall, r.verbose.startup, *(r.verbose.stages.get(k) for k in VERBOSE_STAGES),
             r.verbose.stages.get("compile"), r.verbose.stages.get("execute"), r.verbose.stages.get("jitter")]
            for r in results if r.verbose is not None and r.verbose.stages]
    if rows:
        out += ["Warm process by stage (`a5 ... -v`, best of the -v runs; s): `parse` includes the file checks "
                "(meshes read, images decoded); `counts` = the second pass -v renders for the ray counts (its own "
                "kernel: not part of the command without -v); `startup` = wall - parse - variant - build - "
                "render - filter - write - counts (interpreter, imports before the parse, exit); compile, "
                "execute and jitter are inside render", "",
                format_table(["scene", "wall", "startup", *VERBOSE_STAGES, "compile", "execute", "jitter"], rows),
                ""]
    rows = []
    for r in results:
        if r.inproc is None or not r.inproc.stages:
            continue
        st = r.inproc.stages
        rest = None
        if r.warm is not None:
            rest = r.warm.wall - sum(st.get(k, 0.0) for k in ("parse", "build", "render", "filter", "write"))
        rows.append([r.name, rest] + [st.get(k) for k in STAGES] + [f"{r.inproc.recompiles}/{r.inproc.renders}"])
    if rows:
        out += ["Stages of one render (s; in-process, first render of the scene; `startup` = warm process wall - "
                "parse - build - render - filter - write: interpreter, imports, variant, exit; `recompiled` = "
                "repeated renders of the loaded scene that compiled a kernel again)", "",
                format_table(["scene", "startup", *STAGES, "recompiled"], rows), ""]
    rows = []
    for r in results:
        ip = r.inproc
        rays = ip.rays if ip else (r.warm.rays if r.warm else {})
        total = sum(rays.get(k, 0) for k in RAY_KINDS) if rays else None
        rows.append([r.name] + [rays.get(k) for k in RAY_KINDS] + [
            total / ip.kernel_execute / 1e6 if ip and total else None,
            ip.kernel_execute if ip else None,
            ip.floor.get("camera") if ip else None,
            ip.floor.get("secondary") if ip else None,
            ip.floor.get("shadow") if ip else None,
            ip.floor_total if ip else None,
            _ratio(ip.kernel_execute, ip.floor_total) if ip else None,
            ip.floor_first_hits_total if ip else None])
    out += ["Rays and the traversal floor (in-process, warm kernels, best of repeat; times in s). `floor` = "
            "Mitsuba's traversal of exactly the rays the kernel cast (its ray log: every ray-tree node by "
            "`ray_intersect`, every shadow ray by `ray_test`), in the kernel's packet order, on the `stock=True` "
            "scene (spheres and planes as shapes); `floor (first hits)` = the former estimate (each camera "
            "ray's first-hit secondary and shadow rays repeated by its counts, on the a5 scene)", "",
            format_table(["scene", *RAY_KINDS, "Mrays/s", "kernel", "floor cam", "floor refl+refr",
                          "floor shadow", "floor", "kernel/floor", "floor (first hits)"], rows), ""]
    rows = [[r.name, r.inproc.kernel_execute if r.inproc else None, r.stock.get("direct"), r.stock.get("path"),
             _ratio(r.inproc.kernel_execute if r.inproc else None, r.stock.get("path"))]
            for r in results]
    out += ["Stock Mitsuba, same scene (`stock=True`), render resolution, 1 spp (s, best of repeat)", "",
            format_table(["scene", "a5 kernel", "stock direct", "stock path", "a5 kernel/path"], rows), ""]
    if "4k" in extra:
        run = extra["4k"]
        out += [f"4K: `{extra['4k_cmd']}`: wall {run.wall:.1f} s, peak {run.peak_mb:.0f} MB, exit {run.returncode}"
                + (f"; stages {run.stages}" if run.stages else ""), ""]
    out += _batch_tables(extra)
    errors = [f"- {r.name}: {e}" for r in results for e in r.errors]
    if "batch_error" in extra:
        errors.append(f"- batch: {extra['batch_error']}")
    if errors:
        out += ["Errors:", *errors, ""]
    return "\n".join(out)
