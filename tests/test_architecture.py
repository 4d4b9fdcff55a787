"""The architecture holds where the import contracts cannot say it.

``lint-imports`` (run by ``make check`` and ``make test``) checks the contracts of
pyproject.toml: the layers (every package in one, each importing only those below
it, so the runtime, the lowest, imports nothing else of whexar), the runtime's and
the device links' forbidden imports, and ``acyclic_siblings``: no cycle between
the children of any package, each child taken with everything inside it. What
stays here is what no contract checks:

* a cycle through a package's own ``__init__`` — a package that imports a module of
  its own which imports the package back. ``acyclic_siblings`` looks only at the
  children of each package, not at the package's module beside them, so it passes
  such a cycle; the finder below looks at every module;
* which third-party packages the runtime needs (a contract forbids, it cannot list
  what is allowed);
* that every package says what it holds and what it may import, and that the
  README's layout names every package.
"""

import importlib
import pkgutil
import re
import sys
from collections.abc import Iterator
from pathlib import Path

import grimp

import whexar

ROOT = Path(__file__).resolve().parents[1]


def _cycles(graph: grimp.ImportGraph) -> list[list[str]]:
    """Strongly connected components of more than one module (Tarjan, iterative)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    found: list[list[str]] = []
    counter = 0

    def imported(module: str) -> Iterator[str]:
        return iter(sorted(graph.find_modules_directly_imported_by(module)))

    for root in sorted(graph.modules):
        if root in index:
            continue
        work = [(root, imported(root))]
        index[root] = low[root] = counter
        counter += 1
        stack.append(root)
        on_stack.add(root)
        while work:
            node, children = work[-1]
            child = next(children, None)
            if child is not None:
                if child not in index:
                    index[child] = low[child] = counter
                    counter += 1
                    stack.append(child)
                    on_stack.add(child)
                    work.append(
                        (child, iter(sorted(graph.find_modules_directly_imported_by(child))))
                    )
                elif child in on_stack:
                    low[node] = min(low[node], index[child])
                continue
            work.pop()
            if work:
                low[work[-1][0]] = min(low[work[-1][0]], low[node])
            if low[node] == index[node]:
                component = []
                while True:
                    member = stack.pop()
                    on_stack.discard(member)
                    component.append(member)
                    if member == node:
                        break
                if len(component) > 1:
                    found.append(sorted(component))
    return found


def test_no_module_is_part_of_an_import_cycle() -> None:
    # Every module, packages' own modules included: acyclic_siblings misses a cycle
    # through a package's __init__ (see the module docstring).
    graph = grimp.build_graph("whexar")
    assert len(graph.modules) > 50
    assert _cycles(graph) == []


def test_the_cycle_finder_finds_a_cycle() -> None:
    graph = grimp.ImportGraph()
    for module in ("p", "p.a", "p.b", "p.c"):
        graph.add_module(module)
    graph.add_import(importer="p.a", imported="p.b")
    graph.add_import(importer="p.b", imported="p.c")
    graph.add_import(importer="p.c", imported="p.a")
    assert _cycles(graph) == [["p.a", "p.b", "p.c"]]


def test_the_cycle_finder_finds_what_acyclic_siblings_misses() -> None:
    # p imports its module p.a, which imports p back: no two children of p import each
    # other, so acyclic_siblings keeps it; the cycle finder does not.
    graph = grimp.ImportGraph()
    for module in ("p", "p.a", "p.b"):
        graph.add_module(module)
    graph.add_import(importer="p", imported="p.a")
    graph.add_import(importer="p.a", imported="p")
    assert graph.nominate_cycle_breakers("p") == set()
    assert _cycles(graph) == [["p", "p.a"]]


def test_the_runtime_needs_only_anyio_pydantic_and_numpy() -> None:
    graph = grimp.build_graph("whexar", include_external_packages=True)
    imported = {
        target
        for module in graph.find_descendants("whexar.runtime") | {"whexar.runtime"}
        for target in graph.find_modules_directly_imported_by(module)
    }
    # Its imports of whexar are the contracts' (layers, and the runtime's forbidden list).
    outside = {m for m in imported if m != "whexar" and not m.startswith("whexar.")}
    third_party = outside - set(sys.stdlib_module_names) - {"__future__"}
    assert third_party == {"anyio", "pydantic", "numpy"}


def _packages() -> list[str]:
    return [
        name
        for _, name, is_package in pkgutil.walk_packages(whexar.__path__, "whexar.")
        if is_package
    ]


def test_every_package_says_what_it_holds_and_what_it_may_import() -> None:
    packages = ["whexar", *_packages()]
    assert {"whexar.runtime", "whexar.actors", "whexar.bus", "whexar.sensors"} <= set(packages)
    for name in packages:
        doc = importlib.import_module(name).__doc__ or ""
        assert len(doc.split()) >= 20, f"{name} has no package docstring"
        if name != "whexar":
            assert re.search(r"\b[Mm]ay import\b|\bimports nothing\b", doc), (
                f"{name}'s docstring does not say what it may import"
            )


def test_the_readme_layout_names_every_package_of_whexar() -> None:
    readme = (ROOT / "README.md").read_text()
    section = readme.split("## Layout", 1)[1].split("\n## ", 1)[0]
    block = section.split("```", 2)[1]
    listed = set(re.findall(r"^  (\w+)(?:/|\.py)", block, flags=re.M))
    present = {
        path.stem if path.is_file() else path.name
        for path in (ROOT / "whexar").iterdir()
        if not path.name.startswith(("_", "."))
        and (path.suffix == ".py" or (path / "__init__.py").exists())
    }
    assert listed == present
