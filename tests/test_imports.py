"""The house's import rules, read from the source (nothing is imported or run):

- no view imports the runner: the report, leaderboard, dashboard, play, export and plots
  read run directories through `deepphy.plan`, never through the code that runs them;
- no import circle among deepphy's modules (annotations' imports included);
- an import inside a function only where it defers a heavy import or one a command may
  never need, with its reason in a comment (on its line, or just above its block of imports).
  The CLI's commands all import what they need when they run: a fast terminal is its reason,
  said once in its docstring.
"""

from __future__ import annotations

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
PACKAGE = ROOT / "deepphy"
RUNNER = "deepphy.runner"
VIEWS = ("deepphy.metrics", "deepphy.dashboard", "deepphy.play", "deepphy.export", "deepphy.plots")
LAZY_BY_DESIGN = {"deepphy.cli"}  # every command imports what it needs when it runs (its docstring says why)


def module_name(path: Path) -> str:
    parts = path.relative_to(ROOT).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


MODULES = {module_name(p): p for p in PACKAGE.rglob("*.py")}


def resolved(name: str) -> str | None:
    """The deepphy module an import names (a name imported from a package may be a module)."""
    while name and name not in MODULES:
        name = name.rpartition(".")[0]
    return name or None


def imports(path: Path) -> list[tuple[ast.stmt, list[str], bool]]:
    """(statement, deepphy modules it imports, whether it is inside a function) for every import
    that runs: those under `if TYPE_CHECKING:` are for a type checker's eyes only and import
    nothing when the program runs (the report's models named in the metric registry's
    annotations)."""
    tree = ast.parse(path.read_text())
    inner = {id(n) for f in ast.walk(tree) if isinstance(f, (ast.FunctionDef, ast.AsyncFunctionDef))
             for n in ast.walk(f) if isinstance(n, (ast.Import, ast.ImportFrom))}
    typing_only = {id(n) for f in ast.walk(tree) if isinstance(f, ast.If) and ast.unparse(f.test) == "TYPE_CHECKING"
                   for n in ast.walk(f) if isinstance(n, (ast.Import, ast.ImportFrom))}
    package = module_name(path) if path.name == "__init__.py" else module_name(path).rpartition(".")[0]
    out = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            names = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:  # relative
                base = ".".join(package.split(".")[: len(package.split(".")) - node.level + 1] + ([base] if base else []))
            names = [f"{base}.{a.name}" for a in node.names] + [base]
        else:
            continue
        if id(node) in typing_only:
            continue
        found = [m for m in dict.fromkeys(resolved(n) for n in names if n.startswith("deepphy")) if m]
        out.append((node, found, id(node) in inner))
    return out


GRAPH = {name: {m for _, found, _ in imports(path) for m in found if m != name} for name, path in MODULES.items()}


def reaches(start: str) -> dict[str, list[str]]:
    """Every module `start` imports, straight or through others, with the chain that does."""
    chains = {start: [start]}
    todo = [start]
    while todo:
        here = todo.pop()
        for nxt in sorted(GRAPH[here]):
            if nxt not in chains:
                chains[nxt] = chains[here] + [nxt]
                todo.append(nxt)
    return chains


def test_no_view_imports_the_runner():
    views = [m for m in MODULES if m.startswith(VIEWS)]
    assert len(views) >= 10, views  # the views were found
    reached = {view: reaches(view).get(RUNNER) for view in views}
    assert not {v: chain for v, chain in reached.items() if chain}, "a view reaches the runner"


def test_no_import_circle():
    circles = []
    for name in MODULES:
        for nxt in GRAPH[name]:
            back = reaches(nxt).get(name)
            if back:
                circles.append(" -> ".join([name, *back]))
    assert not circles, circles


def reason_given(lines: list[str], node: ast.stmt, block_start: int) -> bool:
    """A comment on the import's lines, or on the line above the block of imports it is in."""
    own = lines[node.lineno - 1 : node.end_lineno]
    return any("#" in line for line in own[:1] + own[-1:]) or "#" in lines[block_start - 2]


def test_imports_inside_functions_say_why():
    unexplained = []
    for name, path in MODULES.items():
        if name in LAZY_BY_DESIGN:
            continue
        lines = path.read_text().splitlines()
        found = [node for node, _, inner in imports(path) if inner]
        starts = {}
        for node in sorted(found, key=lambda n: n.lineno):  # a block: imports on consecutive lines
            prev = next((s for s in starts if starts[s] == node.lineno - 1), None)
            starts[node] = node.end_lineno
            node.block_start = prev.block_start if prev is not None else node.lineno
        rel = str(path.relative_to(ROOT))
        unexplained += [f"{rel}:{n.lineno}: {lines[n.lineno - 1].strip()}" for n in found
                        if not reason_given(lines, n, n.block_start)]
    assert not unexplained, "\n".join(unexplained)


def test_the_checks_see_what_they_check(tmp_path):
    """The rules above would catch what they forbid: a view importing the runner through
    another module, a circle, an import in a function without a reason."""
    assert reaches("deepphy.cli").get(RUNNER), "the CLI runs evaluations through the runner"
    assert resolved("deepphy.envs.Task") == "deepphy.envs" and resolved("deepphy.runs.store") == "deepphy.runs.store"
    source = tmp_path / "x.py"
    source.write_text("def f():\n    import json\n\n\ndef g():\n    # the reason\n    import json\n    import re\n")
    lines = source.read_text().splitlines()
    nodes = [n for n in ast.walk(ast.parse(source.read_text())) if isinstance(n, ast.Import)]
    assert [reason_given(lines, n, start) for n, start in zip(nodes, (2, 7, 7))] == [False, True, True]
