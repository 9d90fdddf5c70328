#!/usr/bin/env python3
"""Lists the longest function bodies in C++ files (a brace counter, comments and strings skipped).

Usage: tools/function_sizes.py [--most N] [--over L] FILE_OR_DIR...
A function is a top-level-in-its-scope `{` whose preceding text ends with `)` (optionally followed
by const/override/noexcept/-> type/initializer list); its length is the number of lines from the
line of its signature's name to the closing brace. Lambdas and nested blocks count in their
enclosing function.
"""
import argparse
import os
import re
import sys


def strip(text):
    """Blanks comments, string and char literals, keeping newlines."""
    out, i, n = [], 0, len(text)
    while i < n:
        c = text[i]
        if text.startswith("//", i):
            j = text.find("\n", i)
            j = n if j < 0 else j
            out.append(" " * (j - i)); i = j
        elif text.startswith("/*", i):
            j = text.find("*/", i + 2)
            j = n if j < 0 else j + 2
            out.append(re.sub(r"[^\n]", " ", text[i:j])); i = j
        elif c == 'R' and text.startswith('R"', i):
            m = re.match(r'R"([^(]*)\(', text[i:])
            end = text.find(")" + m.group(1) + '"', i) + len(m.group(1)) + 2
            out.append(re.sub(r"[^\n]", " ", text[i:end])); i = end
        elif c in "\"'":
            j = i + 1
            while j < n and text[j] != c:
                j += 2 if text[j] == "\\" else 1
            out.append(" " * (j + 1 - i)); i = j + 1
        else:
            out.append(c); i += 1
    return "".join(out)


SIG_END = re.compile(r"\)\s*(const|override|final|noexcept|mutable|\s|->\s*[\w:<>,\s*&]+)*$|"
                     r"\)\s*:\s*[\s\S]*$")


def functions(path):
    text = strip(open(path, encoding="utf-8", errors="replace").read())
    stack = []  # (kind, start_offset)
    result = []
    last_end = 0  # offset after the last ; { or }
    for i, c in enumerate(text):
        if c == "{":
            head = text[last_end:i]
            inside_fn = any(k == "fn" for k, _ in stack)
            kind = "block"
            if not inside_fn and re.search(r"\)\s*(const|override|final|noexcept|\s)*$", head) \
                    and not re.search(r"\b(if|for|while|switch|catch)\s*\(", head.strip()[:12]):
                kind = "fn"
            elif not inside_fn and re.search(r"\)\s*(const|noexcept|\s)*:\s*\w", head):
                kind = "fn"  # constructor with initializer list
            stack.append((kind, last_end if kind == "fn" else i))
            last_end = i + 1
        elif c == "}":
            if stack:
                kind, start = stack.pop()
                if kind == "fn":
                    head = text[start:i]
                    skip = len(head) - len(head.lstrip())
                    first = text.count("\n", 0, start + skip) + 1
                    last = text.count("\n", 0, i) + 1
                    name = re.findall(r"([~\w:]+)\s*\(", text[start:text.find("{", start)])
                    result.append((last - first + 1, path, first, name[0] if name else "?"))
            last_end = i + 1
        elif c == ";":
            last_end = i + 1
    return result


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--most", type=int, default=10)
    ap.add_argument("--over", type=int, default=0, help="exit 1 if any function is longer")
    ap.add_argument("paths", nargs="+")
    a = ap.parse_args()
    files = []
    for p in a.paths:
        if os.path.isdir(p):
            for root, _, names in os.walk(p):
                files += [os.path.join(root, f) for f in names if f.endswith((".cc", ".h", ".cpp"))]
        else:
            files.append(p)
    rows = sorted((r for f in sorted(files) for r in functions(f)), reverse=True)
    for length, path, line, name in rows[: a.most]:
        print(f"{length:5d}  {path}:{line}  {name}")
    if a.over and rows and rows[0][0] > a.over:
        print(f"FAIL: {sum(1 for r in rows if r[0] > a.over)} function(s) longer than {a.over} lines")
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
