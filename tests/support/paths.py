"""Where the tests' files are, wherever a test module sits in tests/: the repository, its docs and firmware, the
tests' data and vectors, and the BROAD trials beside the checkout (../shared/data/broad)."""

from __future__ import annotations

from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
TESTS = ROOT / "tests"
DATA = TESTS / "fixtures"
VECTORS = TESTS / "vectors"
DOCS = ROOT / "docs"
FIRMWARE = ROOT / "firmware"
BROAD = ROOT.parent / "shared" / "data" / "broad"
EXCERPT = DATA / "broad_07_fast_rotation_excerpt.csv.gz"  # 20 s of BROAD trial 07 (tests/fixtures/README.md)
