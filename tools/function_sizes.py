#!/usr/bin/env python3
"""Lists the longest function bodies in C++ files (a brace counter, comments and strings skipped).

Usage: tools/function_sizes.py [--most N] [--over L] [--allow NAME=LINES]... FILE_OR_DIR...
--over L fails (exit 1) on any function longer than L lines, except those named by --allow:
NAME=LINES lets the function NAME (as listed) keep at most LINES lines, a known exception that
may shrink but not grow; an --allow that no longer matches a function over L is reported, so the
list stays current.
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
    ap.add_argument("--allow", action="append", default=[], metavar="NAME=LINES",
                    help="a known exception to --over: NAME may have at most LINES lines")
    ap.add_argument("paths", nargs="+")
    a = ap.parse_args()
    allowed = {}
    for item in a.allow:
        name, _, lines = item.rpartition("=")
        if not name or not lines.isdigit():
            ap.error(f"--allow {item}: expected NAME=LINES")
        allowed[name] = int(lines)
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
    if not a.over:
        return 0
    over = [r for r in rows if r[0] > a.over]
    failed = [r for r in over if r[0] > allowed.get(r[3], a.over)]
    stale = sorted(set(allowed) - {r[3] for r in over})
    for length, path, line, name in over:
        if (length, path, line, name) not in failed:
            print(f"known exception: {name} ({path}:{line}) {length} lines, allowed {allowed[name]}")
    for name in stale:
        print(f"FAIL: --allow {name}: no function of that name is over {a.over} lines any more;"
              " drop it from the list")
    for length, path, line, name in failed:
        limit = allowed.get(name, a.over)
        print(f"FAIL: {name} ({path}:{line}) has {length} lines; at most {limit}")
    if failed or stale:
        return 1
    print(f"no function over {a.over} lines except the {len(over)} known exception(s)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
