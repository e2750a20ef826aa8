#!/usr/bin/env python3
"""List Rust functions longer than N lines (from the `fn` line to its closing brace)."""
import re, sys, pathlib
N = int(sys.argv[1]) if len(sys.argv) > 1 else 120
roots = sys.argv[2:] or ["crates", "benches", "python/src", "tests"]
fn_re = re.compile(r'^\s*(pub(\([^)]*\))?\s+)?(const\s+)?(async\s+)?(unsafe\s+)?(extern\s+"C"\s+)?fn\s+(\w+)')

def blank(text):
    """Comments and string/char literals replaced by spaces, newlines kept."""
    out = []; i = 0; n = len(text)
    while i < n:
        c = text[i]
        if text.startswith("//", i):
            j = text.find("\n", i); j = n if j < 0 else j
            out.append(" " * (j - i)); i = j
        elif text.startswith("/*", i):
            j = text.find("*/", i + 2); j = n if j < 0 else j + 2
            out.append(re.sub(r"[^\n]", " ", text[i:j])); i = j
        elif c == 'r' and re.match(r'r#*"', text[i:i+10]) and (i == 0 or not (text[i-1].isalnum() or text[i-1] == '_')):
            m = re.match(r'r(#*)"', text[i:]); hashes = m.group(1)
            end = text.find('"' + hashes, i + len(m.group(0))); end = n if end < 0 else end + 1 + len(hashes)
            out.append(re.sub(r"[^\n]", " ", text[i:end])); i = end
        elif c == '"':
            j = i + 1
            while j < n and text[j] != '"':
                j += 2 if text[j] == '\\' else 1
            out.append(re.sub(r"[^\n]", " ", text[i:j+1])); i = j + 1
        elif c == "'" and re.match(r"'(\\.|[^'\\])'", text[i:i+4]) or (c == "'" and re.match(r"'\\u\{[0-9a-fA-F]+\}'", text[i:i+12])):
            m = re.match(r"'(\\u\{[0-9a-fA-F]+\}|\\.|[^'\\])'", text[i:])
            out.append(" " * len(m.group(0))); i += len(m.group(0))
        else:
            out.append(c); i += 1
    return "".join(out)

out = []
for root in roots:
    for p in pathlib.Path(root).rglob("*.rs"):
        if "target" in p.parts: continue
        lines = blank(p.read_text()).split("\n")
        for i, line in enumerate(lines):
            m = fn_re.match(line)
            if not m: continue
            depth = 0; started = False; j = i
            while j < len(lines):
                for ch in lines[j]:
                    if ch == '{': depth += 1; started = True
                    elif ch == '}': depth -= 1
                if started and depth <= 0: break
                if not started and lines[j].rstrip().endswith(';'): break
                j += 1
            n = j - i + 1
            if started and n > N:
                out.append((n, f"{p}:{i+1}", m.group(7)))
for n, loc, name in sorted(out, reverse=True):
    print(n, name, loc)
print(len(out), "functions over", N, "lines")
