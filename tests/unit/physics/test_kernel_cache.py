"""The kernels' numba cache is dropped when any kernel source changes (numba alone checks only the defining file)."""

from __future__ import annotations

from pathlib import Path

import pytest

from millctl.physics import kernels


def _tree(tmp_path: Path) -> tuple[Path, Path, Path]:
    package = tmp_path / "physics" / "kernels"
    (package / "__pycache__").mkdir(parents=True)
    (tmp_path / "physics" / "__pycache__").mkdir()
    (package / "trig.py").write_text("def f(): return 1\n")
    (package / "events.py").write_text("def g(): return 2\n")
    (tmp_path / "physics" / "legacy_kernel.py").write_text("def h(): return 3\n")
    cached = package / "__pycache__" / "events.g-1.py311.nbi"
    legacy = tmp_path / "physics" / "__pycache__" / "legacy_kernel.h-1.py311.nbi"
    return package, cached, legacy


def test_editing_a_callee_drops_its_callers_cache(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv("NUMBA_CACHE_DIR", raising=False)
    package, cached, legacy = _tree(tmp_path)
    kernels._drop_stale_cache(package)  # first sight: no stamp, nothing trusted
    for path in (cached, legacy):
        path.write_text("compiled")
    kernels._drop_stale_cache(package)
    assert cached.exists() and legacy.exists()  # sources unchanged: the cache is kept
    (package / "trig.py").write_text("def f(): return 10\n")  # a callee of events.g, in another file
    kernels._drop_stale_cache(package)
    assert not cached.exists() and not legacy.exists()
    cached.write_text("recompiled")
    kernels._drop_stale_cache(package)
    assert cached.exists()


def test_a_cache_dir_of_ones_own_is_left_alone(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    package, cached, _ = _tree(tmp_path)
    cached.write_text("compiled")
    monkeypatch.setenv("NUMBA_CACHE_DIR", str(tmp_path / "elsewhere"))
    kernels._drop_stale_cache(package)
    assert cached.exists() and not (package / "__pycache__" / "kernel-sources.sha256").exists()
