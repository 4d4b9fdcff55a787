"""The README's Python examples run, and print what the README says they print."""

import contextlib
import io
import re
from pathlib import Path

README = Path(__file__).resolve().parents[1] / "README.md"


def _blocks() -> list[str]:
    return re.findall(r"```python\n(.*?)```", README.read_text(), flags=re.S)


def test_readme_examples_run_and_print_what_they_claim() -> None:
    blocks = _blocks()
    assert blocks, "the README has no Python example"
    for block in blocks:
        out = io.StringIO()
        namespace: dict[str, object] = {}
        with contextlib.redirect_stdout(out):
            exec(compile(block, "README.md", "exec"), namespace)
            # A block that defines tests (a user's own, "Testing with faults") runs them.
            for name, value in namespace.items():
                if name.startswith("test_") and callable(value):
                    value()
        claimed = [
            line.split("# -> ", 1)[1].split("(")[0].strip()
            for line in block.splitlines()
            if "# -> " in line
        ]
        printed = [" ".join(line.split()) for line in out.getvalue().splitlines()]
        for claim in claimed:
            assert " ".join(claim.split()) in printed, (claim, printed)
