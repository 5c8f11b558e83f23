#!/usr/bin/env python3
"""docs/equations.md maps every numbered equation of the paper to the one function that implements it. This test
keeps that table true, cheaply (it reads text; it builds and runs nothing):

  * every equation the paper numbers (Eq. 1-28 with its sub-letters, listed below) has exactly one row, and no row
    names an equation the paper does not have;
  * every row's file exists, declares the function's namespace (`namespace topocal::model`, ...), and holds the
    function: its name followed by "(" and, for a member, its class (`Class::Name(` or a `struct`/`class Class`);
  * every relative link in the document resolves to a file of the checkout (and to a heading, for #anchors).

A failure names the line of docs/equations.md and the equation. Standard library only.

usage: equations_test.py [SOURCE_DIR]   (default: the checkout this script lives in)
"""
import os
import re
import sys

SOURCE = os.path.abspath(sys.argv[1] if len(sys.argv) > 1 else os.path.join(os.path.dirname(__file__), "..", ".."))
DOC = os.path.join(SOURCE, "docs", "equations.md")

# Every numbered equation of the paper (/work/shared/paper/000_93d7604b5d6ba57d.txt), sub-letters as printed.
PAPER_EQUATIONS = [
    "1", "2a", "2b", "3", "4", "5", "6a", "6b", "6c", "7", "8", "9", "10", "11a", "11b", "11c", "12", "13a", "13b",
    "14a", "14b", "14c", "15a", "15b", "16", "17", "18a", "18b", "19", "20", "21", "22", "23", "24", "25", "26",
    "27a", "27b", "28a", "28b",
]
# Leading components of a qualified name that are namespaces (the rest are classes and the function).
NAMESPACES = {"topocal", "model", "calib", "correct", "topo", "pipeline", "report"}


def split_row(line):
    """Cells of a markdown table row; '\\|' is a literal pipe inside a cell."""
    cells = re.split(r"(?<!\\)\|", line.strip())
    return [c.strip() for c in cells[1:-1]]


def code_span(cell):
    m = re.fullmatch(r"`([^`]+)`", cell)
    return m.group(1) if m else None


def github_anchor(heading):
    return re.sub(r"[^\w\- ]", "", heading.strip().lower()).replace(" ", "-")


def check_function(qualified, path, text):
    """None if `qualified` is found in `text` (the file at `path`), else why not."""
    parts = qualified.split("::")
    ns = []
    while parts and parts[0] in NAMESPACES:
        ns.append(parts.pop(0))
    if len(ns) < 2 or ns[0] != "topocal" or not parts:
        return f"`{qualified}` is not of the form topocal::<module>::[Class::]Function"
    if not re.search(r"\bnamespace\s+" + re.escape("::".join(ns)) + r"\b", text):
        return f"{path} does not declare namespace {'::'.join(ns)}"
    name, classes = parts[-1], parts[:-1]
    if not re.search(r"\b" + re.escape(name) + r"\s*(<[^;{()]*>)?\s*\(", text):
        return f"function {name} does not occur in {path}"
    if classes:
        cls = classes[-1]
        out_of_class = re.search(r"\b" + re.escape(cls) + r"::" + re.escape(name) + r"\s*\(", text)
        in_class = re.search(r"\b(struct|class)\s+" + re.escape(cls) + r"\b", text)
        if not (out_of_class or in_class):
            return f"neither {cls}::{name}( nor a struct/class {cls} occurs in {path}"
    return None


def main():
    with open(DOC, encoding="utf-8") as f:
        lines = f.read().split("\n")
    failures = []

    def fail(lineno, message):
        failures.append(f"docs/equations.md:{lineno}: {message}")

    # The equations table: the first table whose header starts with "Eq.".
    header = next((i for i, l in enumerate(lines) if l.startswith("|") and split_row(l)[:1] == ["Eq."]), None)
    if header is None:
        print("docs/equations.md: no table with an 'Eq.' column", file=sys.stderr)
        return 1
    columns = split_row(lines[header])
    expected_columns = ["Eq.", "What it is", "Function", "File"]
    if columns[:4] != expected_columns:
        fail(header + 1, f"the table's first columns must be {expected_columns}, not {columns[:4]}")
    rows = {}
    i = header + 2  # past the separator
    while i < len(lines) and lines[i].startswith("|"):
        lineno = i + 1
        cells = split_row(lines[i])
        i += 1
        if len(cells) != len(columns):
            fail(lineno, f"{len(cells)} cells where the header has {len(columns)}")
            continue
        eq, what, function_cell, file_cell = cells[:4]
        label = f"Eq. {eq}"
        if not re.fullmatch(r"\d+[a-z]?", eq):
            fail(lineno, f"'{eq}' is not an equation number (digits and an optional sub-letter)")
            continue
        if eq in rows:
            fail(lineno, f"{label} has a second row (first on line {rows[eq]})")
            continue
        rows[eq] = lineno
        if eq not in PAPER_EQUATIONS:
            fail(lineno, f"{label} is not a numbered equation of the paper")
        if not what:
            fail(lineno, f"{label}: empty 'What it is'")
        function, path = code_span(function_cell), code_span(file_cell)
        if not function or not path:
            fail(lineno, f"{label}: Function and File must each be one `code span`")
            continue
        full = os.path.join(SOURCE, path)
        if not os.path.isfile(full):
            fail(lineno, f"{label}: file {path} does not exist")
            continue
        with open(full, encoding="utf-8") as f:
            why = check_function(function, path, f.read())
        if why:
            fail(lineno, f"{label}: {why}")

    for eq in PAPER_EQUATIONS:
        if eq not in rows:
            fail(header + 1, f"Eq. {eq} of the paper has no row")

    # Relative links of the whole document.
    for n, line in enumerate(lines, 1):
        for target in re.findall(r"\]\(([^)\s]+)\)", line):
            if re.match(r"[a-z]+:", target):
                continue  # http:, https:, mailto:
            path, _, anchor = target.partition("#")
            full = os.path.normpath(os.path.join(os.path.dirname(DOC), path)) if path else DOC
            if not os.path.isfile(full):
                fail(n, f"link {target}: {os.path.relpath(full, SOURCE)} does not exist")
                continue
            if anchor and full.endswith(".md"):
                with open(full, encoding="utf-8") as f:
                    anchors = {github_anchor(m.group(1)) for m in re.finditer(r"^#+\s+(.*)$", f.read(), re.M)}
                if anchor not in anchors:
                    fail(n, f"link {target}: no heading with anchor #{anchor} in {os.path.relpath(full, SOURCE)}")

    for message in failures:
        print(message, file=sys.stderr)
    if failures:
        print(f"{len(failures)} problem(s) in docs/equations.md", file=sys.stderr)
        return 1
    print(f"docs/equations.md: {len(rows)} equations mapped, every file and function found")
    return 0


if __name__ == "__main__":
    sys.exit(main())
