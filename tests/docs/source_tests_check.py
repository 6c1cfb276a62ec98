#!/usr/bin/env python3
"""Every library source has a test: one named after it, or a row in
docs/testing.md naming test files that exist.

Usage: source_tests_check.py <repository root>
"""
import pathlib
import re
import sys


def main() -> int:
    root = pathlib.Path(sys.argv[1])
    sources = sorted(
        p.relative_to(root).as_posix()
        for top in ("services", "clients")
        for p in (root / top).rglob("*.cc")
        if p.name != "main.cc" and not p.name.endswith("_main.cc"))
    tests = [p.relative_to(root).as_posix() for p in (root / "tests").rglob("*")]
    table = {}
    for line in (root / "docs/testing.md").read_text().splitlines():
        m = re.match(r"\| `([^`]+)` \| (.*) \|$", line)
        if m:
            table[m.group(1)] = re.findall(r"`(tests/[^`]+)`", m.group(2))
    problems = []
    for source in sources:
        stem = pathlib.PurePosixPath(source).stem
        named = [t for t in tests
                 if re.search(rf"/{re.escape(stem)}(_\w+)?_test\.(cc|py)$", t)]
        if source in table:
            if not table[source]:
                problems.append(f"{source}: its row in docs/testing.md names no test file")
            for t in table[source]:
                if not (root / t).is_file():
                    problems.append(f"{source}: docs/testing.md names {t}, which does not exist")
        elif not named:
            problems.append(f"{source}: no tests/**/{stem}_test.cc and no row in docs/testing.md")
    for source in table:
        if source not in sources:
            problems.append(f"docs/testing.md lists {source}, which is not a library source")
    for p in problems:
        print(p)
    print(f"{len(sources)} library sources, {len(table)} tested under other names, "
          f"{len(problems)} problems")
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main())
