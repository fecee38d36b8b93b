#!/usr/bin/env python3
"""The library speaks of fields, not command-line flags: no string literal in its code
(mapping/, sources/, perception/, gp/, util/, builder/) holds a flag such as "--max-step". Each front
spells the fields its own way (apps/src/io/cli_text.cpp for the command line)."""
import pathlib
import re
import sys

root = pathlib.Path(sys.argv[1])
flag = re.compile(r"(?<![-\w])--[a-z][a-z0-9-]*")


def literals(code):
    """The string literals of C++ `code`, comments left out, with their line numbers."""
    out, i, line, n = [], 0, 1, len(code)
    while i < n:
        c = code[i]
        if code.startswith("//", i):
            j = code.find("\n", i)
            i = n if j < 0 else j
        elif code.startswith("/*", i):
            j = code.find("*/", i + 2)
            j = n if j < 0 else j + 2
            line += code.count("\n", i, j)
            i = j
        elif c == "'":  # a character literal: skip it, escapes included
            j = i + 1
            while j < n and code[j] != "'":
                j += 2 if code[j] == "\\" else 1
            i = j + 1
        elif c == '"':
            raw = re.match(r'R"([^(]*)\(', code[i - 1:i + 20]) if i > 0 and code[i - 1] == "R" else None
            if raw:
                end = code.find(")" + raw.group(1) + '"', i)
                text, j = code[i:end], end + len(raw.group(1)) + 2
            else:
                j = i + 1
                while j < n and code[j] != '"':
                    j += 2 if code[j] == "\\" else 1
                text, j = code[i + 1:j], j + 1
            out.append((line, text))
            line += code.count("\n", i, j)
            i = j
        else:
            if c == "\n":
                line += 1
            i += 1
    return out


found = []
for module in ("mapping", "sources", "perception", "gp", "util", "builder"):
    for path in sorted((root / module).rglob("*")):
        if path.suffix not in (".cpp", ".hpp", ".h"):
            continue
        for line, text in literals(path.read_text(errors="replace")):
            for m in flag.finditer(text):
                found.append(f"{path.relative_to(root)}:{line}: {m.group(0)} in \"{text}\"")
if found:
    print("library strings that name command-line flags (name the field, in backquotes, instead):")
    print("\n".join(found))
    sys.exit(1)
print("no library string names a command-line flag")
