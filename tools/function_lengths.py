#!/usr/bin/env python3
"""Lengths of the functions in native/ (C++) and addon/ (Python), longest first.

    /usr/bin/python3 tools/function_lengths.py [--over N]

The house rule (issue 12): no function over 120 lines, most under 60, so
that the next engineer can hold each one in their head. tests/cli/
test_code_shape.py enforces the 120-line limit with this module.

Python functions are measured with `ast` (decorators excluded). C++ is
measured by brace matching from a definition's opening line, skipping
comments, string and character literals: a definition is a line whose
brace opens a block after a parameter list `)` (optionally followed by
const, noexcept, override, a trailing return type or a constructor's
initialiser list), which is not a control statement. Lambdas inside a
function count towards it; a lambda at namespace scope counts on its own.
"""
import argparse
import ast
import re
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
CONTROL = re.compile(r"^\s*(\}\s*)?(if|for|while|switch|catch|else|do|return|namespace|class|struct|enum|union)\b")


def python_functions(path):
    tree = ast.parse(path.read_text(), str(path))
    for node in ast.walk(tree):
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
            yield node.name, node.lineno, node.end_lineno - node.lineno + 1


def strip_cpp(text):
    """The source with comments, strings and character literals blanked (newlines kept)."""
    out, i, n = [], 0, len(text)
    while i < n:
        c = text[i]
        if text.startswith("//", i):
            j = text.find("\n", i)
            i = n if j < 0 else j
        elif text.startswith("/*", i):
            j = text.find("*/", i + 2)
            j = n if j < 0 else j + 2
            out.append("\n" * text.count("\n", i, j))
            i = j
        elif c == 'R' and text.startswith('R"', i):
            m = re.match(r'R"([^(]*)\(', text[i:])
            end = text.find(")" + m.group(1) + '"', i) if m else -1
            j = n if end < 0 else end + len(m.group(1)) + 2
            out.append('""' + "\n" * text.count("\n", i, j))
            i = j
        elif c in "\"'":
            j = i + 1
            while j < n and text[j] != c:
                j += 2 if text[j] == "\\" else 1
            out.append(c + c)
            i = j + 1
        else:
            out.append(c)
            i += 1
    return "".join(out)


def cpp_functions(path):
    lines = strip_cpp(path.read_text()).split("\n")
    depth_stack = []  # (kind, start line, name) per open brace
    for number, line in enumerate(lines, 1):
        for k, c in enumerate(line):
            if c == "{":
                head = " ".join(lines[max(0, number - 4):number - 1] + [line[:k]])
                head = head[head.rfind(";") + 1:].rsplit("}", 1)[-1]
                is_function = (re.search(r"\)\s*(const|noexcept|override|final|mutable|->[^{]*|:[^{]*)*\s*$",
                                         head) is not None and not CONTROL.match(line[:k])
                               and not any(kind == "function" for kind, _, _ in depth_stack))
                names = [m for m in re.findall(r"([~\w:]+)\s*\(", head)
                         if not m.startswith("__") and m not in {"alignas", "decltype", "sizeof", "noexcept"}]
                depth_stack.append(("function" if is_function else "block", number, names[0] if names else "?"))
            elif c == "}" and depth_stack:
                kind, start, name = depth_stack.pop()
                if kind == "function":
                    yield name, start, number - start + 1


def functions(root=REPO):
    """(length, path, line, name) of every function in native/ and addon/."""
    found = []
    for path in sorted((root / "native").rglob("*")):
        if path.suffix in {".h", ".cpp"}:
            found += [(length, path, line, name) for name, line, length in cpp_functions(path)]
    for path in sorted((root / "addon").rglob("*.py")):
        found += [(length, path, line, name) for name, line, length in python_functions(path)]
    return sorted(found, key=lambda f: -f[0])


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--over", type=int, default=60, help="list functions longer than this (default 60)")
    args = ap.parse_args()
    found = functions()
    for length, path, line, name in found:
        if length > args.over:
            print(f"{length:5d}  {path.relative_to(REPO)}:{line}  {name}")
    over = sum(1 for f in found if f[0] > args.over)
    print(f"{len(found)} functions, {over} over {args.over} lines, longest {found[0][0] if found else 0}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
