"""The architecture holds: no import cycles, a standalone runtime, documented packages.

``lint-imports`` (run by ``make test``) checks the contracts of pyproject.toml;
these tests state the same rules where a contract cannot, module by module.
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


def test_the_runtime_needs_only_anyio_pydantic_and_numpy() -> None:
    graph = grimp.build_graph("whexar", include_external_packages=True)
    imported = {
        target
        for module in graph.find_descendants("whexar.runtime") | {"whexar.runtime"}
        for target in graph.find_modules_directly_imported_by(module)
    }
    outside = {m for m in imported if not m.startswith("whexar.runtime")}
    assert not {m for m in outside if m.startswith("whexar")}
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
