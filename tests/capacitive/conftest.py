"""Fixtures of the capacitive tests: a private mesh cache per test."""

from __future__ import annotations

import pytest


@pytest.fixture(autouse=True)
def _private_mesh_cache(tmp_path, monkeypatch):
    monkeypatch.setenv("TWINSENSE_CACHE_DIR", str(tmp_path / "cache"))
