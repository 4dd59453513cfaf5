"""The package's layout: the task's vocabulary imports nothing of ours, and no new import cycle."""

import ast
from pathlib import Path

import dualarm.task as task
from dualarm.experiments.run_logs import EVAL_READ
from dualarm.training.run_dir import EVAL_COLUMNS

SRC = Path(__file__).resolve().parents[1] / "src"
#: Cycles that remain, each with the issue item that removes it; the list may only shrink.
KNOWN_CYCLES: set[frozenset[str]] = set()


def import_graph() -> dict[str, set[str]]:
    """Module -> the project modules it imports (anywhere in it, but not for type checking only)."""
    files = {}
    for path in (SRC / "dualarm").rglob("*.py"):
        parts = path.relative_to(SRC).with_suffix("").parts
        files[".".join(parts[:-1] if parts[-1] == "__init__" else parts)] = path

    def imported(path: Path, name: str) -> set[str]:
        found = set()

        class Visitor(ast.NodeVisitor):
            def visit_If(self, node):
                if not (isinstance(node.test, ast.Name) and node.test.id == "TYPE_CHECKING"):
                    self.generic_visit(node)

            def visit_Import(self, node):
                found.update(a.name for a in node.names)

            def visit_ImportFrom(self, node):
                if node.module:
                    found.add(node.module)
                    found.update(f"{node.module}.{a.name}" for a in node.names)

        Visitor().visit(ast.parse(path.read_text()))
        return {m for m in found if m in files and m != name}

    return {name: imported(path, name) for name, path in files.items()}


def cycles(graph: dict[str, set[str]]) -> set[frozenset[str]]:
    """The modules of every cycle found by depth-first search, as sets."""
    found, done, stack = set(), set(), []

    def visit(u):
        stack.append(u)
        for v in sorted(graph[u]):
            if v in stack:
                found.add(frozenset(stack[stack.index(v):]))
            elif v not in done:
                visit(v)
        stack.pop()
        done.add(u)

    for name in sorted(graph):
        if name not in done:
            visit(name)
    return found


def test_the_vocabulary_module_imports_nothing_of_the_project():
    assert import_graph()["dualarm.task"] == set()
    assert len(task.JOINT_COLUMNS) == 14 and task.JOINT_COLUMNS[7] == "right_s0"
    assert set(task.GUIDED_CONDITIONS) < set(task.CONDITIONS) < set(task.COMPARED_CONDITIONS)
    assert set(task.COMPARED_CONDITIONS) == set(task.CONDITION_NAMES)
    assert {task.guide_condition(c) for c in task.COMPARED_CONDITIONS} == set(task.CONDITIONS)


def test_no_import_cycle_beyond_the_known_ones():
    assert cycles(import_graph()) <= KNOWN_CYCLES


def package_graph(graph: dict[str, set[str]]) -> dict[str, set[str]]:
    """Package (or top-level module) -> those it imports: ``dualarm.envs.baxter`` counts as
    ``envs``; the root package ``dualarm`` itself is left out (it imports nothing of ours)."""
    def top(module: str) -> str | None:
        parts = module.split(".")
        return parts[1] if len(parts) > 1 else None

    packages: dict[str, set[str]] = {}
    for module, imports in graph.items():
        if top(module) is None:
            continue
        deps = packages.setdefault(top(module), set())
        deps.update(t for t in map(top, imports) if t is not None and t != top(module))
    return packages


def test_no_package_level_import_cycle():
    """The packages form layers (task < kinematics < mocap < demos < constraints < envs < rl <
    training < experiments < cli): a module imports only from its own stage and those below."""
    assert cycles(package_graph(import_graph())) == set()


def test_package_graph_sees_a_cycle_between_packages():
    graph = {"dualarm.a.x": {"dualarm.b.y"}, "dualarm.b.y": set(), "dualarm.b.z": {"dualarm.a.w"},
             "dualarm.a.w": set()}
    assert cycles(package_graph(graph)) == {frozenset("ab")}


def test_cycle_finder_finds_a_cycle():
    assert cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == {frozenset("abc")}


def test_the_report_reads_columns_the_trainer_writes():
    assert set(EVAL_READ) <= set(EVAL_COLUMNS)
