"""docs/protocol.md and the test vectors are generated from the packet table: check they are up to date."""

from __future__ import annotations

import importlib.util

from tests.support.paths import ROOT


def _generator():
    spec = importlib.util.spec_from_file_location("gen_protocol", ROOT / "docs" / "gen_protocol.py")
    assert spec and spec.loader
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_protocol_doc_is_up_to_date() -> None:
    gen = _generator()
    current = gen.DOC.read_text()
    assert current == gen.render_doc(current), "run: .venv/bin/python docs/gen_protocol.py"


def test_vectors_are_up_to_date() -> None:
    gen = _generator()
    assert gen.VECTORS.read_text() == gen.vectors_json(), "run: .venv/bin/python docs/gen_protocol.py"


def test_doc_names_every_packet() -> None:
    from term.core import protocol as p

    doc = (ROOT / "docs" / "protocol.md").read_text()
    for spec in p.PACKETS.values():
        assert f"`{spec.type_id:#04x}` {spec.cls.__name__}" in doc


def test_the_heading_names_the_protocol_version() -> None:
    """docs/protocol.md was headed "version 2" while PROTOCOL_VERSION was 3 (issue 23): the generator writes it."""
    from term.core.protocol import PROTOCOL_VERSION

    first = (ROOT / "docs" / "protocol.md").read_text().splitlines()[0]
    assert first == f"# The Quadrupel link protocol (version {PROTOCOL_VERSION})"
