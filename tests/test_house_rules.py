"""The house rules (DESIGN.md), checked on the sources:

- a number both ends of the link need lives in ``term/core/protocol/`` (or its sibling ``term/core/logformat.py``),
  never as a literal elsewhere: the NUS UUIDs, the lift zero and stick neutral, ``SET_PARAM`` ids and packing, the
  Hello role, the flight modes, the fire button, the log scheme ids, the battery thresholds, the field scales;
- no module under ``term/`` or ``fcb_sim/`` but a ``cli`` (or ``__main__``) imports a ``cli`` module;
- ``term.core.protocol`` imports nothing of the project; ``term.core.logformat`` only the protocol;
  ``fcb_sim`` imports only those two of ``term`` and never Textual;
- the folders of ``term`` are floors (``FLOORS``, docs/architecture.md): a module imports only from its own floor
  and the floors below it, an import under ``if TYPE_CHECKING:`` included;
- the modules of ``term`` and of ``fcb_sim`` import one another without a cycle, TYPE_CHECKING imports included.

Each rule is checked per tree (``term``, ``fcb_sim``, ``bench``), so a failure names the side that broke it.
Comments and strings are blanked before the numeric rules look at the code, so prose may name the numbers.
"""

from __future__ import annotations

import ast
import io
import re
import tokenize
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
TREES = ("term", "fcb_sim", "bench")
HOMES = (Path("term/core/protocol"), Path("term/core/logformat.py"))


def _sources(tree: str) -> list[Path]:
    return sorted(p for p in (ROOT / tree).rglob("*.py")
                  if not any(p.relative_to(ROOT).is_relative_to(home) for home in HOMES))


def _code_only(text: str) -> str:
    """The source with comments and string literals blanked (line structure kept)."""
    lines = text.splitlines(keepends=True)
    out = [list(line) for line in lines]
    try:
        tokens = list(tokenize.generate_tokens(io.StringIO(text).readline))
    except (tokenize.TokenError, SyntaxError):
        return text
    for tok in tokens:
        if tok.type not in (tokenize.COMMENT, tokenize.STRING) and tok.type != getattr(tokenize, "FSTRING_MIDDLE",
                                                                                          -1):
            continue
        (r0, c0), (r1, c1) = tok.start, tok.end
        for r in range(r0, r1 + 1):
            row = out[r - 1]
            start = c0 if r == r0 else 0
            end = c1 if r == r1 else len(row)
            for c in range(start, min(end, len(row))):
                if row[c] != "\n":
                    row[c] = " "
    return "".join("".join(row) for row in out)


# (rule, regex, applies to the raw text (True) or to the code only (False), trees it applies to)
_UUID = re.compile(r"6e40000[1-3]-b5a3-f393-e0a9-e50e24dcca9e", re.I)
RULES: dict[str, tuple[re.Pattern[str], bool, tuple[str, ...]]] = {
    "nus_uuid": (_UUID, True, TREES),
    "name_prefix": (re.compile(r"""["']Quadrupel["']"""), True, TREES),
    "lift_zero_defined": (re.compile(r"\b(LIFT_ZERO|STICK_NEUTRAL)\s*=\s*\d"), False, TREES),
    "lift_compared_with_number": (
        re.compile(r"lift\w*(\.\w+)*\s*(<=|>=|<|>)\s*\d{3,}|\d{3,}\s*(<=|>=|<|>)\s*\w*lift", re.I), False, TREES),
    "set_param_packing": (re.compile(r"\(\s*\d+\s*<<\s*16\s*\)\s*\||SET_PARAM\s*,\s*\(?\s*\d"), False, TREES),
    "set_param_id_compared": (re.compile(r"\bpid\s*==\s*\d"), False, TREES),
    "hello_role_literal": (re.compile(r"Hello\(\s*PROTOCOL_VERSION\s*,\s*\d"), False, TREES),
    "role_constant_defined": (re.compile(r"\bROLE_\w+\s*=\s*\d"), False, TREES),
    "flight_modes_defined": (re.compile(r"\bFLIGHT_MODES\s*=\s*(frozenset|\(|\{|\[)"), False, TREES),
    "fire_button_literal": (re.compile(r"buttons\s*&\s*1\b"), False, TREES),
    "log_scheme_literal": (re.compile(r"scheme\s*==\s*\d"), False, TREES),
    "battery_threshold_literal": (
        re.compile(r"(<|>|<=|>=|=)\s*(10\.5|11\.1|12\.6|1050|1110|1260)\b"), False, ("term", "fcb_sim")),
    "gyro_acc_scale_literal": (re.compile(r"\b16\.4\b|/\s*16384\b|\b16384\.0\b"), False, ("term", "fcb_sim")),
    "field_scale_retyped": (
        re.compile(r"\.(phi|theta|psi|battery|temperature|height|setpoint|vz|board_ms)\s*/\s*(100|1000)(\.0)?\b"),
        False, ("term", "fcb_sim")),
}


def _violations(tree: str, rule: str) -> list[str]:
    pattern, raw, trees = RULES[rule]
    if tree not in trees:
        return []
    found = []
    for path in _sources(tree):
        text = path.read_text(encoding="utf-8")
        body = text if raw else _code_only(text)
        for n, line in enumerate(body.splitlines(), start=1):
            if pattern.search(line):
                found.append(f"{path.relative_to(ROOT)}:{n}: {text.splitlines()[n - 1].strip()}")
    return found


@pytest.mark.parametrize("tree", TREES)
@pytest.mark.parametrize("rule", sorted(RULES))
def test_no_copies_of_protocol_facts(tree: str, rule: str) -> None:
    found = _violations(tree, rule)
    assert not found, f"{rule}: use the name from term.core.protocol:\n" + "\n".join(found)


def test_rules_can_fail() -> None:
    """Each rule catches the copy it is written for (so a passing tree means something)."""
    samples = {
        "nus_uuid": 'X = "6E400001-B5A3-F393-E0A9-E50E24DCCA9E"',
        "name_prefix": 'NAME = "Quadrupel"',
        "lift_zero_defined": "LIFT_ZERO = 512",
        "lift_compared_with_number": "if stick.lift > 512:",
        "set_param_packing": "send(Op.SET_PARAM, (4 << 16) | 2)",
        "set_param_id_compared": "if pid == 3 and v:",
        "hello_role_literal": "Hello(PROTOCOL_VERSION, 1, 0, 1, 7)",
        "role_constant_defined": "ROLE_BOARD = 1",
        "flight_modes_defined": "FLIGHT_MODES = (Mode.MANUAL,)",
        "fire_button_literal": "if pkt.buttons & 1:",
        "log_scheme_literal": "if self.log.scheme == 2:",
        "battery_threshold_literal": "style = 'red' if v < 10.5 else 'green'",
        "gyro_acc_scale_literal": "rate = raw / 16.4",
        "field_scale_retyped": "x = pkt.phi / 100",
    }
    assert set(samples) == set(RULES)
    for rule, line in samples.items():
        pattern, raw, _ = RULES[rule]
        assert pattern.search(line if raw else _code_only(line + "\n")), rule
    assert not RULES["lift_compared_with_number"][0].search(_code_only('"""lift > 500 in prose"""\n'))


# --- imports ------------------------------------------------------------------------------------------------


def _module_name(path: Path) -> str:
    rel = path.relative_to(ROOT).with_suffix("")
    parts = rel.parts[:-1] if rel.name == "__init__" else rel.parts
    return ".".join(parts)


def _type_checking_only(tree: ast.AST) -> set[int]:
    """ids of the import nodes under ``if TYPE_CHECKING:`` (annotations only, not a dependency at run time)."""
    out: set[int] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.If) and "TYPE_CHECKING" in ast.unparse(node.test):
            out.update(id(n) for stmt in node.body for n in ast.walk(stmt))
    return out


def _imports(path: Path, type_checking: bool = True) -> set[str]:
    """Every module ``path`` imports, anywhere in it (a function-level import is a dependency too, and so is one
    under ``if TYPE_CHECKING:`` unless ``type_checking`` is False: a circle through annotations is still a circle)."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    package = _module_name(path).rsplit(".", 0 if path.name == "__init__.py" else 1)[0]
    skip = set() if type_checking else _type_checking_only(tree)
    out: set[str] = set()
    for node in ast.walk(tree):
        if id(node) in skip:
            continue
        if isinstance(node, ast.Import):
            out.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                parent = package.split(".")
                parent = parent[: len(parent) - node.level + 1]
                base = ".".join([*parent, base] if base else parent)
            out.add(base)
            out.update(f"{base}.{alias.name}" for alias in node.names)  # `from term.core import protocol`
    return out


def _all_modules(tree: str) -> dict[str, Path]:
    return {_module_name(p): p for p in sorted((ROOT / tree).rglob("*.py"))}


@pytest.mark.parametrize("tree", ("term", "fcb_sim"))
def test_no_core_module_imports_a_cli(tree: str) -> None:
    bad = []
    for name, path in _all_modules(tree).items():
        if path.name in ("cli.py", "__main__.py"):
            continue
        clis = sorted(m for m in _imports(path) if m.split(".")[-1] == "cli" and m.split(".")[0] in ("term", "fcb_sim"))
        if clis:
            bad.append(f"{name} imports {', '.join(clis)}")
    assert not bad, "only cli/__main__ may import a cli module:\n" + "\n".join(bad)


def test_protocol_imports_nothing_of_the_project() -> None:
    # DESIGN.md: term.core.protocol is pure (stdlib only); the flash-log codec builds on it, never the other way round.
    mods = _all_modules("term")
    protocol = [name for name in mods if name == "term.core.protocol" or name.startswith("term.core.protocol.")]
    assert len(protocol) > 1
    for name in protocol:
        ours = {m for m in _imports(mods[name]) if m.split(".")[0] in ("term", "fcb_sim")}
        assert all(m.startswith("term.core.protocol") for m in ours), f"{name} imports {sorted(ours)}"
    ours = {m for m in _imports(mods["term.core.logformat"]) if m.split(".")[0] in ("term", "fcb_sim")}
    assert all(m.startswith("term.core.protocol") for m in ours)


def test_fcb_sim_uses_only_the_protocol_of_term() -> None:
    allowed = ("term.core.protocol", "term.core.logformat")
    bad = []
    for name, path in _all_modules("fcb_sim").items():
        for m in _imports(path):
            top = m.split(".")[0]
            if top == "textual" or (top == "term" and m not in ("term", "term.core") and not m.startswith(allowed)):
                bad.append(f"{name} imports {m}")
    assert not bad, "\n".join(bad)


def _cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components with more than one module (Tarjan)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on: set[str] = set()
    out: list[list[str]] = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on.add(v)
        for w in graph[v]:
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                out.append(sorted(comp))

    for v in graph:
        if v not in index:
            visit(v)
    return out


def _import_graph(tree: str) -> dict[str, set[str]]:
    mods = _all_modules(tree)
    graph: dict[str, set[str]] = {}
    for name, path in mods.items():
        deps = set()
        for m in _imports(path):
            # `from term.ui.widgets import x` names a module or an attribute: keep what is a module of ours
            while m and m not in mods:
                m = m.rpartition(".")[0]
            # a package's __init__ is not a dependency of its own modules' imports of siblings
            if m and m != name and not name.startswith(m + "."):
                deps.add(m)
        graph[name] = deps
    return graph


@pytest.mark.parametrize("tree", ("term", "fcb_sim"))
def test_no_import_cycles(tree: str) -> None:
    cycles = _cycles(_import_graph(tree))
    assert not cycles, "import cycles:\n" + "\n".join(" <-> ".join(c) for c in cycles)


def test_cycle_finder_can_fail() -> None:
    assert _cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]
    assert _cycles({"a": {"b"}, "b": set()}) == []


# --- floors -------------------------------------------------------------------------------------------------

# term's packages, bottom up (docs/architecture.md draws them): a module imports only its own floor and below.
FLOORS = {"term.core": 1, "term.transports": 2, "term.input": 2, "term.session": 3, "term.data": 4,
          "term.lessons": 5, "term.ui": 6, "term.cli": 7, "term.__main__": 7}


def _floor(module: str) -> int | None:
    for package, floor in FLOORS.items():
        if module == package or module.startswith(package + "."):
            return floor
    return None


def _up_imports(graph: dict[str, set[str]]) -> list[str]:
    bad = []
    for name, deps in sorted(graph.items()):
        mine = _floor(name)
        for dep in sorted(deps):
            theirs = _floor(dep)
            if mine is not None and theirs is not None and theirs > mine:
                bad.append(f"{name} (floor {mine}) imports {dep} (floor {theirs})")
    return bad


def test_every_term_module_has_a_floor() -> None:
    homeless = [m for m in _all_modules("term") if m != "term" and _floor(m) is None]
    assert not homeless, f"modules outside the floors (put them in a floor's package): {homeless}"


def test_no_import_goes_up_a_floor() -> None:
    bad = _up_imports(_import_graph("term"))
    assert not bad, "an import up a floor (move the code down, or pass it in):\n" + "\n".join(bad)


def test_floor_check_can_fail() -> None:
    assert _up_imports({"term.core.freshness": {"term.session.model"}, "term.session.model": {"term.core.link"}}) == [
        "term.core.freshness (floor 1) imports term.session.model (floor 3)"]
