"""a5mi.runtime.llvm: an LLVM older than 16 is refused with one line naming the fix, before Dr.Jit can abort."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from a5mi.runtime import llvm


@pytest.mark.parametrize(
    ("name", "major"),
    [("libLLVM-15.so", 15), ("libLLVM-14.0.6.so.1", 14), ("libLLVM.so.19.1", 19), ("libLLVM-19.so", 19),
     ("libLLVM.18.dylib", 18), ("libLLVM.so", None)],
)
def test_major_from_file_name(name: str, major: int | None) -> None:
    assert llvm._major_from_name(name) == major


def test_forced_old_llvm_is_refused_with_the_fix(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    fake = tmp_path / "libLLVM-15.so"
    fake.write_bytes(b"\x7fELF")  # never loaded: the version comes from the name
    monkeypatch.setenv("DRJIT_LIBLLVM_PATH", str(fake))
    with pytest.raises(llvm.LLVMError) as err:
        llvm.check()
    msg = str(err.value)
    assert "LLVM 15" in msg and "apt-get install -y libllvm19" in msg and "unset DRJIT_LIBLLVM_PATH" in msg
    assert "\n" not in msg


def test_forced_unreadable_library_is_refused(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    fake = tmp_path / "libLLVM.so"
    fake.write_text("not a library")
    monkeypatch.setenv("DRJIT_LIBLLVM_PATH", str(fake))
    with pytest.raises(llvm.LLVMError, match="not a readable libLLVM"):
        llvm.check()


def test_this_machine_has_a_usable_llvm(monkeypatch: pytest.MonkeyPatch) -> None:
    """`make setup` installs libllvm19, so the unforced search must find LLVM >= 16 here."""
    monkeypatch.delenv("DRJIT_LIBLLVM_PATH", raising=False)
    lib = llvm.check()
    assert lib.major is not None and lib.major >= 16


def test_real_llvm15_library_is_detected_without_name_version(tmp_path: Path) -> None:
    """A real libLLVM 15 under a version-less name is recognised by the missing LLVMGetVersion symbol."""
    real = Path("/usr/lib/x86_64-linux-gnu/libLLVM-15.so.1")
    if not real.exists():
        pytest.skip("no libLLVM 15 on this machine")
    link = tmp_path / "libLLVM.so"
    link.symlink_to(real)
    assert llvm.probe(str(link)).major == 15


def test_variant_activation_refuses_old_llvm_in_a_subprocess(tmp_path: Path) -> None:
    """The whole import path: no Dr.Jit abort, one line, non-zero exit."""
    fake = tmp_path / "libLLVM-15.so"
    fake.write_bytes(b"\x7fELF")
    code = (
        "import sys\n"
        "from a5mi.runtime.variant import activate, VariantError\n"
        "try:\n    activate('llvm')\n"
        "except VariantError as e:\n    print('a5: error:', e, file=sys.stderr); sys.exit(2)\n"
    )
    env = {"DRJIT_LIBLLVM_PATH": str(fake), "PATH": "/usr/bin:/bin"}
    proc = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=120)
    assert proc.returncode == 2
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("a5: error: Dr.Jit would load LLVM 15")


def test_a5_cli_with_only_llvm15_prints_the_fix_and_writes_nothing(tmp_path: Path, scenes_dir: Path) -> None:
    """The real command line, LLVM 15 forced: one line, exit 2, no output file, no abort."""
    fake = tmp_path / "libLLVM-15.so"
    fake.write_bytes(b"\x7fELF")
    out = tmp_path / "out.png"
    env = {"DRJIT_LIBLLVM_PATH": str(fake), "PATH": "/usr/bin:/bin", "A5_DATA": str(scenes_dir.parent)}
    proc = subprocess.run(
        [sys.executable, "-m", "a5mi", "-input", str(scenes_dir / "scene11_cube.txt"), "-size", "20", "20",
         "-output", str(out)],
        env=env, capture_output=True, text=True, timeout=120, cwd=tmp_path,
    )
    assert proc.returncode == 2, proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and "LLVM 15" in lines[0] and "apt-get install -y libllvm19" in lines[0]
    assert "Traceback" not in proc.stderr and not out.exists()


def test_library_loaded_through_ld_library_path_is_checked(tmp_path: Path) -> None:
    """An LLVM 15 ``libLLVM.so`` first on LD_LIBRARY_PATH is what Dr.Jit loads (the file
    search of llvm.find prefers the newest); the render is refused with one line, exit 2, instead of
    aborting (134, LLVM ERROR) at the first kernel."""
    old = next((p for p in ("/usr/lib/x86_64-linux-gnu/libLLVM-15.so.1", "/usr/lib/x86_64-linux-gnu/libLLVM-15.so")
                if Path(p).exists()), None)
    if old is None:
        pytest.skip("no LLVM 15 library on this machine")
    (tmp_path / "lib").mkdir()
    (tmp_path / "lib" / "libLLVM.so").symlink_to(old)
    (tmp_path / "s.txt").write_text("PerspectiveCamera { center 0 0 10 direction 0 0 -1 up 0 1 0 angle 20 }\n"
                                    "Materials { numMaterials 1 Material { diffuseColor 1 0 0 } }\n"
                                    "Group { numObjects 1 MaterialIndex 0 Sphere { center 0 0 0 radius 1 } }\n")
    import os

    env = {**os.environ, "LD_LIBRARY_PATH": str(tmp_path / "lib")}
    env.pop("DRJIT_LIBLLVM_PATH", None)
    p = subprocess.run([sys.executable, "-m", "a5mi", "-input", "s.txt", "-output", "o.png", "-size", "8", "8",
                        "-q"], cwd=tmp_path, capture_output=True, text=True, env=env, timeout=120)
    assert p.returncode == 2, p.stderr[-500:]
    lines = p.stderr.strip().splitlines()
    assert len(lines) == 1 and "Dr.Jit loaded LLVM 15" in lines[0] and "LD_LIBRARY_PATH=" in lines[0]
    assert not (tmp_path / "o.png").exists()


def test_loaded_reads_the_process_maps(tmp_path: Path) -> None:
    maps = tmp_path / "maps"
    maps.write_text("7f00-7f01 r-xp 00000000 08:01 1 /usr/lib/x86_64-linux-gnu/libLLVM-15.so.1\n"
                    "7f01-7f02 r--p 00000000 08:01 1 /usr/lib/x86_64-linux-gnu/libLLVM-15.so.1\n"
                    "7f02-7f03 r--p 00000000 08:01 2 /usr/lib/libLLVMSupport.a.not-a-library\n")
    assert [(lib.path, lib.major) for lib in llvm.loaded(str(maps))] == [
        ("/usr/lib/x86_64-linux-gnu/libLLVM-15.so.1", 15)]
    with pytest.raises(llvm.LLVMError, match="Dr.Jit loaded LLVM 15"):
        llvm.check_loaded(str(maps))
