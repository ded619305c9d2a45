"""The module graph: no import cycles, and optional dependencies imported only where needed.

The layering itself (which package may import which) is checked by ``lint-imports`` with the
contracts in ``pyproject.toml``; these tests look at every module. The graph is grimp's (the
graph import-linter checks): every import statement in ``src/urdfpost``, those inside functions
included.
"""

from __future__ import annotations

import itertools
import subprocess
import sys
from collections.abc import Iterable, Mapping

import grimp
import numpy as np
import pytest

from urdfpost.errors import UrdfpostError

#: Imports under ``if TYPE_CHECKING:`` that close a cycle and wait for a fix (importer, imported).
#: None today; an entry whose cycle is gone fails the test.
KNOWN_TYPE_HINT_CYCLES: set[tuple[str, str]] = set()


def import_cycles(imports: Mapping[str, Iterable[str]]) -> list[list[str]]:
    """The cycles of a directed graph: one per strongly connected component of more than one
    module (or a module that imports itself), each as a closed chain ``[a, b, ..., a]``.

    Parameters
    ----------
    imports : mapping of str to iterable of str
        The modules each module imports.

    Returns
    -------
    list of list of str
        Sorted by their first module; empty for an acyclic graph.
    """
    graph = {m: sorted(set(targets)) for m, targets in imports.items()}
    for targets in list(graph.values()):
        for t in targets:
            graph.setdefault(t, [])
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    on_stack: set[str] = set()
    stack: list[str] = []
    components: list[list[str]] = []
    for root in sorted(graph):
        if root in index:
            continue
        index[root] = low[root] = len(index)
        stack.append(root)
        on_stack.add(root)
        work = [(root, iter(graph[root]))]
        while work:  # Tarjan's algorithm, without recursion
            node, children = work[-1]
            for child in children:
                if child not in index:
                    index[child] = low[child] = len(index)
                    stack.append(child)
                    on_stack.add(child)
                    work.append((child, iter(graph[child])))
                    break
                if child in on_stack:
                    low[node] = min(low[node], index[child])
            else:
                work.pop()
                if work:
                    parent = work[-1][0]
                    low[parent] = min(low[parent], low[node])
                if low[node] == index[node]:
                    component = []
                    while True:
                        member = stack.pop()
                        on_stack.discard(member)
                        component.append(member)
                        if member == node:
                            break
                    if len(component) > 1 or node in graph[node]:
                        components.append(sorted(component))
    return sorted(_chain_through(graph, c) for c in components)


def _chain_through(graph: Mapping[str, list[str]], component: list[str]) -> list[str]:
    """A closed chain from the component's first module back to it, inside the component."""
    start, members = component[0], set(component)
    previous = {start: ""}
    frontier = [start]
    while frontier:  # breadth first: the shortest way back
        following = []
        for node in frontier:
            for child in graph[node]:
                if child == start:
                    chain = [node]
                    while chain[-1] != start:
                        chain.append(previous[chain[-1]])
                    return [start, *reversed(chain[:-1]), start] if node != start else [start] * 2
                if child in members and child not in previous:
                    previous[child] = node
                    following.append(child)
        frontier = following
    raise AssertionError(f"no cycle through {start}")  # pragma: no cover - a component has one


def module_imports(
    graph: grimp.ImportGraph, drop: Iterable[tuple[str, str]] = ()
) -> dict[str, set[str]]:
    """Each module of the graph and the modules it imports, without the imports ``drop``."""
    dropped = set(drop)
    return {
        m: {t for t in graph.find_modules_directly_imported_by(m) if (m, t) not in dropped}
        for m in graph.modules
    }


def describe(graph: grimp.ImportGraph, cycles: list[list[str]]) -> str:
    """The cycles, each import with its line."""
    lines = []
    for chain in cycles:
        lines.append(" -> ".join(chain))
        for importer, imported in itertools.pairwise(chain):
            for detail in graph.get_import_details(importer=importer, imported=imported)[:1]:
                lines.append(f"    {importer} l.{detail['line_number']}: {detail['line_contents']}")
    return "\n".join(lines)


@pytest.fixture(scope="module")
def runtime_graph() -> grimp.ImportGraph:
    return grimp.build_graph("urdfpost", exclude_type_checking_imports=True, cache_dir=None)


@pytest.fixture(scope="module")
def whole_graph() -> grimp.ImportGraph:
    return grimp.build_graph("urdfpost", cache_dir=None)


# -- cycles ------------------------------------------------------------------------------------


def test_the_cycle_finder_finds_cycles():
    assert import_cycles({"a": ["b"], "b": ["c"], "c": []}) == []
    assert import_cycles({"a": ["b"], "b": ["c"], "c": ["a"], "d": ["a"]}) == [["a", "b", "c", "a"]]
    assert import_cycles({"p": ["p"], "q": []}) == [["p", "p"]]
    two = import_cycles({"a": ["b"], "b": ["a"], "x": ["y"], "y": ["z"], "z": ["y"]})
    assert two == [["a", "b", "a"], ["y", "z", "y"]]
    deep = {f"m{k:04d}": [f"m{k + 1:04d}"] for k in range(5000)}
    deep["m5000"] = ["m0000"]
    assert len(import_cycles(deep)[0]) == 5002  # no recursion limit


def test_no_import_cycles(runtime_graph):
    cycles = import_cycles(module_imports(runtime_graph))
    assert not cycles, "import cycles:\n" + describe(runtime_graph, cycles)


def test_no_import_cycles_through_type_hints(whole_graph):
    cycles = import_cycles(module_imports(whole_graph, drop=KNOWN_TYPE_HINT_CYCLES))
    assert not cycles, "import cycles (with the imports for type hints):\n" + describe(
        whole_graph, cycles
    )
    for importer, imported in KNOWN_TYPE_HINT_CYCLES:
        closes = import_cycles(module_imports(whole_graph))
        assert any(importer in c and imported in c for c in closes), (
            f"{importer} -> {imported} closes no cycle any more: "
            "remove it from KNOWN_TYPE_HINT_CYCLES"
        )


# -- optional dependencies ---------------------------------------------------------------------

_IMPORT_ALL = """
import importlib, pkgutil, sys
sys.modules["matplotlib"] = None  # as if not installed: importing it raises ImportError
import urdfpost
names = [m.name for m in pkgutil.walk_packages(urdfpost.__path__, "urdfpost.")]
for name in names:
    if name != "urdfpost.__main__":
        importlib.import_module(name)
print(len(names))
"""


def test_every_module_imports_without_matplotlib():
    done = subprocess.run(
        [sys.executable, "-c", _IMPORT_ALL], capture_output=True, text=True, check=False
    )
    assert done.returncode == 0, done.stderr
    assert int(done.stdout) > 50


def test_plot_without_matplotlib_says_how_to_install_it(tmp_path, monkeypatch):
    from urdfpost.analysis.compare import Comparison
    from urdfpost.analysis.plot import plot_comparison

    for name in ("matplotlib", "matplotlib.figure", "matplotlib.backends.backend_agg"):
        monkeypatch.setitem(sys.modules, name, None)
    nothing = Comparison("m", "cl", True, "heidenhain", [], [], np.zeros(0))
    with pytest.raises(UrdfpostError, match=r"^compare --plot needs matplotlib: pip install "):
        plot_comparison(nothing, tmp_path / "plot.png")
    assert not (tmp_path / "plot.png").exists()
