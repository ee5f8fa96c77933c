"""The xdist workers' staggered imports (tests/support/staggered_imports.py): the names are the ones pytest
imports the test modules under, and each worker's order holds every module once, from its own share on."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

from tests.support.staggered_imports import _test_modules, import_this_workers_share_first, rotated


def test_the_names_are_the_ones_pytest_imported_the_test_modules_under(request: pytest.FixtureRequest) -> None:
    modules = dict(_test_modules(request.config))
    assert modules[__name__] == Path(__file__).resolve()
    imported = [name for name in modules if name in sys.modules]
    assert __name__ in imported
    for name in imported:
        assert Path(sys.modules[name].__file__ or "").resolve() == modules[name], name


def test_each_worker_starts_at_its_share_and_takes_every_module_once() -> None:
    items = list(range(10))
    orders = [rotated(items, k, 3) for k in range(3)]
    assert [o[0] for o in orders] == [0, 3, 6]
    assert all(sorted(o) == items for o in orders)
    assert rotated(items, 0, 1) == items and rotated([], 2, 3) == []


def test_off_xdist_nothing_is_imported_ahead(request: pytest.FixtureRequest) -> None:
    if hasattr(request.config, "workerinput"):
        pytest.skip("this run is on xdist workers")
    assert import_this_workers_share_first(request.config) == 0
