"""a5mi.platform.loading (docs/MITSUBA.md "Loading in parallel"): every Mitsuba object a5mi loads is built on the
calling thread, one after the other; Mitsuba's own default builds them on its thread pool; no plugin loads."""

from __future__ import annotations

import ast
import threading
import time
from pathlib import Path
from typing import Any

import pytest
from helpers import ROOT

from a5mi.platform.loading import load_dict, load_file

#: Objects of the probe scene: enough that Mitsuba's pool takes some of them when it may.
PROBES = 8


@pytest.fixture(scope="module")
def probe_plugin(mi: Any) -> list[int]:
    """A Python BSDF ``a5test_thread_probe`` (integer ``k``) whose constructor records its thread and sleeps 50 ms
    (the GIL is released while it sleeps, so a pool worker can start the next one); returns the thread ids."""
    threads: list[int] = []

    class Probe(mi.BSDF):
        def __init__(self, props: Any) -> None:
            super().__init__(props)
            self.k = props["k"]  # each probe differs: Mitsuba merges equal objects into one
            threads.append(threading.get_ident())
            time.sleep(0.05)

    mi.register_bsdf("a5test_thread_probe", lambda props: Probe(props))
    return threads


def _scene() -> dict[str, Any]:
    return {"type": "scene", **{f"probe{k}": {"type": "a5test_thread_probe", "k": k} for k in range(PROBES)}}


def test_load_dict_builds_every_object_on_the_calling_thread(probe_plugin: list[int], mi: Any) -> None:
    probe_plugin.clear()
    load_dict(_scene())
    assert probe_plugin == [threading.get_ident()] * PROBES


def test_mitsubas_default_builds_them_on_its_pool(probe_plugin: list[int], mi: Any) -> None:
    """What load_dict avoids: with ``parallel=True`` (Mitsuba's default) some constructors run on other threads."""
    probe_plugin.clear()
    mi.load_dict(_scene())
    assert len(probe_plugin) == PROBES and set(probe_plugin) != {threading.get_ident()}


def test_load_file_builds_every_object_on_the_calling_thread(probe_plugin: list[int], mi: Any, tmp_path: Path) -> None:
    values = ["$n", *(str(10 + k) for k in range(1, PROBES))]  # the first from the <default>, 2 below
    probes = "".join(f'<bsdf type="a5test_thread_probe" id="p{k}"><integer name="k" value="{v}"/></bsdf>'
                     for k, v in enumerate(values))
    xml = tmp_path / "probes.xml"
    xml.write_text(f'<scene version="3.0.0"><default name="n" value="1"/>{probes}</scene>')
    probe_plugin.clear()
    load_file(xml, n="2")
    assert probe_plugin == [threading.get_ident()] * PROBES


def _loads(path: Path) -> list[tuple[str, bool, bool]]:
    """Every call in ``path``'s code of a function named ``load_dict``, ``load_file`` or ``load_string`` (Mitsuba's
    or the loader's) and every import of the loader: where, whether it is Mitsuba's own (``mi.load_*``), and
    whether the call passes ``parallel=False``."""
    found = []
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        where = f"{path.relative_to(ROOT)}:{getattr(node, 'lineno', 0)}"
        if isinstance(node, ast.ImportFrom) and node.module == "a5mi.platform.loading":
            found.append((where, False, False))
        elif isinstance(node, ast.Call):
            f = node.func
            name = f.attr if isinstance(f, ast.Attribute) else f.id if isinstance(f, ast.Name) else None
            if name in ("load_dict", "load_file", "load_string"):
                mitsuba = isinstance(f, ast.Attribute) and isinstance(f.value, ast.Name) and f.value.id == "mi"
                serial = any(k.arg == "parallel" and isinstance(k.value, ast.Constant) and k.value.value is False
                             for k in node.keywords)
                found.append((where, mitsuba, serial))
    return found


@pytest.mark.unit
def test_every_load_of_the_project_goes_through_the_loader() -> None:
    loader = ROOT / "a5mi" / "platform" / "loading.py"
    calls = [where for folder in ("a5mi", "plugins", "converters") for path in sorted((ROOT / folder).rglob("*.py"))
             if path != loader for where, mitsuba, _ in _loads(path) if mitsuba]
    assert calls == []
    own = [(where, serial) for where, mitsuba, serial in _loads(loader) if mitsuba]
    assert len(own) == 2 and all(serial for _, serial in own), own


@pytest.mark.unit
def test_no_plugin_loads_anything() -> None:
    """A load inside a constructor swaps Mitsuba's global file resolver under a parallel load's other tasks
    (tests/plugins/materials/test_a5_material.py shows what it did)."""
    assert [where for path in sorted((ROOT / "plugins").rglob("*.py")) for where, _, _ in _loads(path)] == []
