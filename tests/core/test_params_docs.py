"""docs/parameters.md is generated from the parameter table: check it is up to date and names every parameter."""

from __future__ import annotations

import importlib.util

from term.core.protocol import PARAMS, PRESETS
from tests.support.paths import ROOT


def _generator():  # noqa: ANN202
    spec = importlib.util.spec_from_file_location("gen_parameters", ROOT / "docs" / "gen_parameters.py")
    assert spec and spec.loader
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_parameters_doc_is_up_to_date() -> None:
    gen = _generator()
    assert gen.DOC.read_text(encoding="utf-8") == gen.render(), "run: .venv/bin/python docs/gen_parameters.py"


def test_the_docs_name_every_parameter_and_preset() -> None:
    params = (ROOT / "docs" / "parameters.md").read_text(encoding="utf-8")
    protocol = (ROOT / "docs" / "protocol.md").read_text(encoding="utf-8")
    for spec in PARAMS.values():
        assert f"`{spec.name}`" in params and f"`{spec.name}`" in protocol
    for name in PRESETS:
        assert f"`{name}`" in params
