#!/usr/bin/env python3
"""Every relative Markdown link and every backticked repository path in README.md and docs/*.md names a file or
directory that exists. Fails with one line per dead link: FILE:LINE: the link and why.

Checked:
  - [text](target) links that are not URLs (http, https, mailto) or in-page anchors: the target (without its
    #fragment) relative to the Markdown file;
  - `path` spans without spaces that start with a top-level directory of the repository (model/, calib/, docs/...),
    relative to the repository root: {a,b} alternatives are expanded, * and ? must match at least one file, a
    trailing / must be a directory. A generated header (util/version.h) counts when its template (.h.in) exists,
    a module named without its extension (topo/map_image) when one of its files does. Placeholders (<module>) are
    skipped.
Not checked: paths inside fenced code blocks (commands whose outputs do not exist until they run; the README's
blocks are run by tests/readme/readme_test.py).

Usage: dead_links_test.py SOURCE_DIR
       dead_links_test.py --self-test   (the checker finds planted dead links and passes good ones)
"""
import glob
import os
import re
import sys

LINK = re.compile(r"(?<!!)\[[^\]]*\]\(([^)\s]+)(?:\s+\"[^\"]*\")?\)")
IMAGE = re.compile(r"!\[[^\]]*\]\(([^)\s]+)\)")
CODE_SPAN = re.compile(r"(?<!`)`([^`\n]+)`(?!`)")
BRACES = re.compile(r"\{([^{}]*)\}")


def top_level_dirs(root):
    return {e for e in os.listdir(root) if os.path.isdir(os.path.join(root, e)) and not e.startswith(".")
            and e != "build" and not e.startswith("build-")}


def expand_braces(path):
    m = BRACES.search(path)
    if not m:
        return [path]
    out = []
    for alt in m.group(1).split(","):
        out.extend(expand_braces(path[:m.start()] + alt + path[m.end():]))
    return out


def path_exists(root, rel):
    full = os.path.join(root, rel)
    if rel.endswith("/"):
        return os.path.isdir(full)
    if any(c in rel for c in "*?["):
        return bool(glob.glob(full))
    # A generated file counts when its template exists; a module named without extension (topo/map_image) when
    # one of its files does.
    return os.path.exists(full) or os.path.exists(full + ".in") or bool(glob.glob(glob.escape(full) + ".*"))


def check_file(root, md, dirs):
    problems = []
    in_fence = False
    with open(md, encoding="utf-8") as f:
        lines = f.read().split("\n")
    rel_md = os.path.relpath(md, root)
    for number, line in enumerate(lines, 1):
        if line.lstrip().startswith("```"):
            in_fence = not in_fence
            continue
        if in_fence:
            continue
        for pattern in (LINK, IMAGE):
            for m in pattern.finditer(line):
                target = m.group(1)
                if re.match(r"^[a-z][a-z0-9+.-]*:", target) or target.startswith("#"):
                    continue  # a URL (http:, mailto:) or an anchor in the same page
                path = target.split("#", 1)[0]
                resolved = os.path.normpath(os.path.join(os.path.dirname(md), path))
                if not os.path.exists(resolved):
                    problems.append(f"{rel_md}:{number}: link ({target}): "
                                    f"{os.path.relpath(resolved, root)} does not exist")
        for m in CODE_SPAN.finditer(line):
            span = m.group(1).strip()
            if " " in span or "<" in span or "/" not in span or span.split("/", 1)[0] not in dirs:
                continue  # not a path, a placeholder (tests/<module>/), or outside the repository's directories
            for rel in expand_braces(span):
                rel = rel.rstrip(".,:;")
                if not path_exists(root, rel):
                    problems.append(f"{rel_md}:{number}: path `{span}`: {rel} does not exist")
    return problems


def check_tree(root):
    dirs = top_level_dirs(root)
    files = [os.path.join(root, "README.md")] + sorted(glob.glob(os.path.join(root, "docs", "*.md")))
    problems = []
    for md in files:
        problems.extend(check_file(root, md, dirs))
    return files, problems


def self_test():
    import tempfile
    with tempfile.TemporaryDirectory() as root:
        for d in ("docs", "model"):
            os.makedirs(os.path.join(root, d))
        for f in ("model/a.h", "model/a.cc", "docs/b.md"):
            open(os.path.join(root, f), "w").close()
        with open(os.path.join(root, "README.md"), "w") as f:
            f.write("[good](docs/b.md#x) [dead](docs/missing.md) [url](https://example.org) [anchor](#top)\n"
                    "`model/a.{h,cc}` `model/a` `model/gone.h` `model/*.h` `model/` `tests/<module>/` `cmake --build`\n"
                    "```sh\ncat `model/in-a-fence.h`\n```\n")
        with open(os.path.join(root, "docs", "b.md"), "w") as f:
            f.write("[up](../README.md) [dead](../model/none.h)\n")
        _, problems = check_tree(root)
    expected = ["README.md:1: link (docs/missing.md)", "README.md:2: path `model/gone.h`",
                "docs/b.md:1: link (../model/none.h)"]
    found = [p for p in problems if any(p.startswith(e) for e in expected)]
    if len(problems) != len(expected) or len(found) != len(expected):
        print("self-test failed: expected exactly", expected, "got", problems)
        return 1
    print("self-test: the 3 planted dead links found, the 8 good ones passed")
    return 0


def main():
    if sys.argv[1:] == ["--self-test"]:
        return self_test()
    if len(sys.argv) != 2:
        print(__doc__)
        return 2
    files, problems = check_tree(os.path.abspath(sys.argv[1]))
    for p in problems:
        print(p)
    print(f"{len(files)} Markdown files checked, {len(problems)} dead link(s)")
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main())
