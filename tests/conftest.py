"""Shared fixtures: the active Mitsuba variant and the course data folder (``$A5_DATA`` or ../shared/a5)."""

from __future__ import annotations

from pathlib import Path

import pytest

from a5mi import data_dir


@pytest.fixture(scope="session")
def a5_data() -> Path:
    """The course data; the suite needs it (CI has ../shared/a5 beside the clone)."""
    root = data_dir()
    if not (root / "SPEC.md").is_file():
        pytest.fail(f"course data not found at {root}: set A5_DATA to the folder holding SPEC.md and scenes/")
    return root


@pytest.fixture(scope="session")
def scenes_dir(a5_data: Path) -> Path:
    return a5_data / "scenes"


@pytest.fixture(scope="session")
def variant() -> str:
    """Activate the JIT variant once per session (llvm_ad_rgb unless A5MI_VARIANT says otherwise)."""
    from a5mi.variant import activate

    return activate()


_SESSION_CACHE: str | None = None


def pytest_configure(config: pytest.Config) -> None:
    """Keep the glibc rand() prefix cache (a5mi.glibc_rand) of this test session out of the user's home."""
    import os
    import tempfile

    global _SESSION_CACHE
    if "A5MI_CACHE_DIR" not in os.environ:
        _SESSION_CACHE = tempfile.mkdtemp(prefix="a5mi-test-cache-")
        os.environ["A5MI_CACHE_DIR"] = _SESSION_CACHE


def pytest_unconfigure(config: pytest.Config) -> None:
    import os
    import shutil

    if _SESSION_CACHE is not None:
        shutil.rmtree(_SESSION_CACHE, ignore_errors=True)
        os.environ.pop("A5MI_CACHE_DIR", None)
