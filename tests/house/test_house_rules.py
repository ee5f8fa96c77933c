"""The house rules (DESIGN.md), checked on the sources:

- a number both ends of the link need lives in ``term/core/protocol/`` (or its sibling ``term/core/logformat.py``),
  never as a literal elsewhere: the NUS UUIDs, the lift zero and stick neutral, ``SET_PARAM`` ids and packing, the
  Hello role, the flight modes, the fire button, the log scheme ids, the battery thresholds, the field scales;
- no module under ``term/`` or ``fcb_sim/`` but a ``cli`` (or ``__main__``) imports a ``cli`` module;
- ``term.core.protocol`` imports nothing of the project; ``term.core.logformat`` only the protocol;
  ``fcb_sim`` imports only those two of ``term`` and never Textual;
- ``term`` reaches ``fcb_sim`` through one seam, the simulator launcher (``SIM_SEAM``), by an import or by code in
  a string (``python -c "from fcb_sim ..."``);
- the folders of ``term`` and of ``fcb_sim`` are floors (``FLOORS``, docs/architecture.md): a module imports only
  from its own floor and the floors below it, an import inside a function or under ``if TYPE_CHECKING:`` included;
- the modules of ``term`` and of ``fcb_sim`` import one another without a cycle, TYPE_CHECKING imports included;
  importing ``a.b.c`` runs ``a/b/__init__`` too, so it counts as an import of the package.

Each rule is checked per tree (``term``, ``fcb_sim``, ``bench``), so a failure names the side that broke it.
Comments and strings are blanked before the numeric rules look at the code, so prose may name the numbers.
"""

from __future__ import annotations

import ast
import functools
import io
import re
import tokenize
from pathlib import Path

import pytest

from tests.support.paths import ROOT

TREES = ("term", "fcb_sim", "bench")
HOMES = (Path("term/core/protocol"), Path("term/core/logformat.py"))
SIM_SEAM = "term.session.sim"  # the simulator launcher: the only module of term that knows fcb_sim


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


@functools.cache
def _text(path: Path) -> str:
    """A source's text, read once per run (the rules below look at every file many times; none changes meanwhile)."""
    return path.read_text(encoding="utf-8")


@functools.cache
def _code_of(path: Path) -> str:
    return _code_only(_text(path))


@functools.cache
def _parsed(path: Path) -> ast.Module:
    return ast.parse(_text(path))


def _violations(tree: str, rule: str) -> list[str]:
    pattern, raw, trees = RULES[rule]
    if tree not in trees:
        return []
    found = []
    for path in _sources(tree):
        text = _text(path)
        if not pattern.search(text):
            continue  # (blanking comments and strings can only take matches away: tokenize only the suspects)
        body = text if raw else _code_of(path)
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
    rel = (path.relative_to(ROOT) if path.is_relative_to(ROOT) else Path(path.name)).with_suffix("")
    parts = rel.parts[:-1] if rel.name == "__init__" else rel.parts
    return ".".join(parts)


def _type_checking_only(tree: ast.AST) -> set[int]:
    """ids of the import nodes under ``if TYPE_CHECKING:`` (annotations only, not a dependency at run time)."""
    out: set[int] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.If) and "TYPE_CHECKING" in ast.unparse(node.test):
            out.update(id(n) for stmt in node.body for n in ast.walk(stmt))
    return out


@functools.cache
def _imports(path: Path, type_checking: bool = True) -> frozenset[str]:
    """Every module ``path`` imports, anywhere in it (a function-level import is a dependency too, and so is one
    under ``if TYPE_CHECKING:`` unless ``type_checking`` is False: a circle through annotations is still a circle)."""
    tree = _parsed(path)
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
    return frozenset(out)


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
            # importing a.b.c runs a/__init__ and a/b/__init__ first: each is a dependency too, except a package's
            # own __init__ for its modules' imports of siblings (it is already loading)
            while m:
                if m in mods and m != name and not name.startswith(m + "."):
                    deps.add(m)
                m = m.rpartition(".")[0]
        graph[name] = deps
    return graph


@pytest.mark.parametrize("tree", ("term", "fcb_sim"))
def test_no_import_cycles(tree: str) -> None:
    cycles = _cycles(_import_graph(tree))
    assert not cycles, "import cycles:\n" + "\n".join(" <-> ".join(c) for c in cycles)


def test_an_import_of_a_module_depends_on_its_packages() -> None:
    """The cycle issue 32 found: estimation/__init__ imported a module outside the package inside a function, and
    that module imported estimation.base, which runs estimation/__init__ again."""
    graph = _import_graph("fcb_sim")
    assert "fcb_sim.estimation" in graph["fcb_sim.hosts.m0emu"]  # it imports fcb_sim.estimation.ikf_fixed
    assert "fcb_sim.estimation" not in graph["fcb_sim.estimation.ikf"]  # a sibling's import: the package is loading


def test_cycle_finder_can_fail() -> None:
    assert _cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]
    assert _cycles({"a": {"b"}, "b": set()}) == []


# --- floors -------------------------------------------------------------------------------------------------

# Each program's packages, bottom up (docs/architecture.md draws them): a module imports only its own floor and
# below. Packages on one floor do not import each other's modules more than the graph needs (no cycle).
FLOORS = {"term.core": 1, "term.transports": 2, "term.input": 2, "term.session": 3, "term.data": 4,
          "term.lessons": 5, "term.ui": 6, "term.cli": 7, "term.__main__": 7,
          "fcb_sim.errors": 0, "fcb_sim.cbuild": 0, "fcb_sim.world": 1, "fcb_sim.estimation": 1, "fcb_sim.board": 2,
          "fcb_sim.hosts": 3,
          "fcb_sim.lab": 4, "fcb_sim.cli": 5, "fcb_sim.__main__": 5}


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


@pytest.mark.parametrize("tree", ("term", "fcb_sim"))
def test_every_module_has_a_floor(tree: str) -> None:
    homeless = [m for m in _all_modules(tree) if m != tree and _floor(m) is None]
    assert not homeless, f"modules outside the floors (put them in a floor's package): {homeless}"


@pytest.mark.parametrize("tree", ("term", "fcb_sim"))
def test_no_import_goes_up_a_floor(tree: str) -> None:
    bad = _up_imports(_import_graph(tree))
    assert not bad, "an import up a floor (move the code down, or pass it in):\n" + "\n".join(bad)


# --- the one seam from term to fcb_sim ----------------------------------------------------------------------

_CODE_IN_STRING = re.compile(r"\b(from|import)\s+fcb_sim\b")


def _docstrings(tree: ast.AST) -> set[int]:
    out = set()
    for node in ast.walk(tree):
        if isinstance(node, (ast.Module, ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef)) and node.body:
            first = node.body[0]
            if isinstance(first, ast.Expr) and isinstance(first.value, ast.Constant):
                out.add(id(first.value))
    return out


def _reaches_fcb_sim(path: Path) -> list[str]:
    """The imports of fcb_sim in a module of term, and the fcb_sim imports inside its string literals (the code a
    child process is started with, ``python -c "from fcb_sim ..."``, which no import statement shows)."""
    found = sorted(m for m in _imports(path) if m.split(".")[0] == "fcb_sim")
    tree = _parsed(path)
    prose = _docstrings(tree)
    for node in ast.walk(tree):
        if (isinstance(node, ast.Constant) and isinstance(node.value, str) and id(node) not in prose
                and _CODE_IN_STRING.search(node.value)):
            found.append(f"code in a string: {node.value[:60]!r}")
    return found


def test_term_reaches_fcb_sim_only_through_the_simulator_launcher() -> None:
    mods = _all_modules("term")
    bad = [f"{name}: {', '.join(found)}" for name, path in mods.items()
           if name != SIM_SEAM and (found := _reaches_fcb_sim(path))]
    assert not bad, f"only {SIM_SEAM} may reach fcb_sim:\n" + "\n".join(bad)
    assert _reaches_fcb_sim(mods[SIM_SEAM]), "the seam is where term starts the simulator"


def test_seam_check_can_fail(tmp_path: Path) -> None:
    code = tmp_path / "m.py"
    code.write_text('"""from fcb_sim import x is prose here."""\ncmd = ["-c", "from fcb_sim.cli import main"]\n')
    assert _reaches_fcb_sim(code) == ["code in a string: 'from fcb_sim.cli import main'"]


# --- the tests' own house ------------------------------------------------------------------------------------

TEST_FOLDERS = ("core", "transports", "input", "session", "data", "lessons", "ui", "cli", "world", "estimation",
                "board", "hosts", "lab", "firmware", "platform", "packaging", "house")


def _test_modules() -> dict[str, Path]:
    return {_module_name(p): p for p in sorted((ROOT / "tests").rglob("*.py"))}


def test_every_test_file_sits_in_a_floors_folder() -> None:
    """tests/<floor>/test_*.py, as the code's floors (docs/architecture.md); rigs and helpers in tests/support/."""
    stray = [str(p.relative_to(ROOT)) for p in (ROOT / "tests").rglob("test_*.py")
             if p.parent.parent != ROOT / "tests" or p.parent.name not in TEST_FOLDERS]
    assert not stray, f"put these in a floor's folder under tests/ ({', '.join(TEST_FOLDERS)}): {stray}"


def test_no_test_imports_a_test_module_or_a_benchmark() -> None:
    """Shared rigs live in tests/support/ (bench/ may use them); a test importing another test, or a benchmark,
    ties two files that should change alone."""
    bad = []
    for name, path in _test_modules().items():
        for m in sorted(_imports(path)):
            parts = m.split(".")
            if parts[0] == "bench" or (parts[0] == "tests" and any(x.startswith("test_") for x in parts[1:])):
                bad.append(f"{name} imports {m}")
    assert not bad, "move what is shared into tests/support/:\n" + "\n".join(bad)


# --- sizes --------------------------------------------------------------------------------------------------

CLASS_MAX_LINES = 450  # a class does one job and fits in a few screens (DESIGN.md)
MODULE_MAX_LINES = 800


def _oversized(paths: list[Path], class_max: int = CLASS_MAX_LINES, module_max: int = MODULE_MAX_LINES) -> list[str]:
    out = []
    for path in paths:
        text = _text(path)
        if (n := text.count("\n")) > module_max:
            out.append(f"{path.relative_to(ROOT)}: {n} lines (at most {module_max})")
        for node in ast.walk(_parsed(path)):
            if isinstance(node, ast.ClassDef) and (n := node.end_lineno - node.lineno + 1) > class_max:
                out.append(f"{path.relative_to(ROOT)}: class {node.name} {n} lines (at most {class_max})")
    return out


@pytest.mark.parametrize("tree", ("term", "fcb_sim"))
def test_no_class_or_module_outgrows_its_job(tree: str) -> None:
    big = _oversized(sorted((ROOT / tree).rglob("*.py")))
    assert not big, "split these by job:\n" + "\n".join(big)


def test_size_check_can_fail() -> None:
    board = ROOT / "fcb_sim" / "board" / "board.py"
    assert _oversized([board]) == []
    found = _oversized([board], class_max=100, module_max=100)
    assert len(found) == 2 and "class Board" in found[1], found
