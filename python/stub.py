#!/usr/bin/env python3
"""Writes the Python package's type stub, ``halftone/__init__.pyi``, from ``stub.pyi.in`` and
the library's one option table as the command line prints it (``halftone options --json``):
``convert()`` gets a typed keyword for every option, and ``Format`` lists the formats
written. A new option therefore needs no edit in the Python package; the stub is not kept in
git, it is written here before a wheel or an sdist is built (python/ci.sh,
scripts/release.sh).

    python3 python/stub.py [HALFTONE]     # HALFTONE: the command line, target/release/halftone

Only the standard library is used. The stub is replaced atomically, and left untouched when
its bytes would not change.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

HERE = Path(__file__).resolve().parent
TEMPLATE = HERE / "stub.pyi.in"
STUB = HERE / "halftone" / "__init__.pyi"

# The typed value each kind of option takes from Python (text is parsed as on a command
# line, so a `str` is always taken too; the stub names what a caller means).
PATH = "Union[str, os.PathLike[str]]"
TYPES = {
    "bool": "bool",
    "int": "int",
    "number": "float",
    "text": "str",
    "path": PATH,
    "number|text": "Union[float, str]",
    "int|text": "Union[int, str]",
    "text|pair": "Union[str, Tuple[int, int]]",
}


def literal(values: list[str]) -> str:
    return "Literal[" + ", ".join(json.dumps(v) for v in values) + "]"


def python_type(option: dict) -> str:
    """The annotation of one option's keyword."""
    if option["name"] == "format":
        return "Format"
    if option["kind"] == "text" and option["choices"] == "fixed":
        return literal(option["values"])
    try:
        return TYPES[option["kind"]]
    except KeyError:
        raise SystemExit(f"stub.py: option {option['name']}: unknown kind {option['kind']!r}")


def render(table: dict, template: str) -> str:
    """The stub's text: the template with the options and the formats filled in."""
    taken = {"image", "preset", "presets", "linear", "threads"}
    lines = []
    for o in table["options"]:
        if o["name"] in taken:
            raise SystemExit(f"stub.py: option {o['name']} is also written in stub.pyi.in")
        lines.append(f"    {o['name']}: Optional[{python_type(o)}] = None,")
    formats = next(o["values"] for o in table["options"] if o["name"] == "format")
    for marker in ("@OPTIONS@", "@FORMATS@"):
        if template.count(marker) != 1:
            raise SystemExit(f"stub.py: {TEMPLATE}: {marker} must appear once")
    return template.replace("@OPTIONS@", "\n".join(lines)).replace(
        "@FORMATS@", ", ".join(json.dumps(f) for f in formats) + ","
    )


def main() -> int:
    cli = sys.argv[1] if len(sys.argv) > 1 else str(HERE.parent / "target/release/halftone")
    try:
        out = subprocess.run([cli, "options", "--json"], check=True, capture_output=True)
    except (OSError, subprocess.CalledProcessError) as e:
        print(f"stub.py: {cli} options --json: {e}", file=sys.stderr)
        return 1
    try:
        table = json.loads(out.stdout)
    except ValueError as e:
        print(f"stub.py: {cli} options --json: not JSON: {e}", file=sys.stderr)
        return 1
    text = render(table, TEMPLATE.read_text(encoding="utf-8"))
    if STUB.exists() and STUB.read_text(encoding="utf-8") == text:
        return 0
    fd, tmp = tempfile.mkstemp(dir=STUB.parent, prefix=".__init__.pyi.")
    try:
        with os.fdopen(fd, "w", encoding="utf-8") as f:
            f.write(text)
        os.chmod(tmp, 0o644)
        os.replace(tmp, STUB)
    except BaseException:
        os.unlink(tmp)
        raise
    print(f"stub.py: wrote {STUB}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
