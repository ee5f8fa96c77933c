"""`term params --sim set` checks the rules between parameters with the board's values before it sends (issue 34)."""

from __future__ import annotations

import subprocess
import sys


def test_term_params_set_names_the_rule_and_sends_nothing() -> None:
    out = subprocess.run([sys.executable, "-m", "term.cli.main", "params", "--sim", "set", "link.timeout_ms", "50"],
                         capture_output=True, text=True, timeout=120)
    said = out.stdout + out.stderr
    assert out.returncode != 0 and "link.timeout_ms ≥ 2 × link.heartbeat_ms" in said, said
