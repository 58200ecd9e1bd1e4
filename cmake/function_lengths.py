#!/usr/bin/env python3
"""Lists C++ function bodies longer than a limit (lines from the opening to the closing brace).

A brace-matching heuristic, not a parser: comments, strings and character literals are blanked,
then each '{' opened directly inside a namespace, class or file scope whose statement text holds a
'(' starts a function body (lambdas and blocks inside a body count towards their function).
Usage: function_lengths.py [--max N] FILE_OR_DIR...   exit status 1 when any body exceeds N.
"""
import argparse
import pathlib
import re
import sys

SCOPE_WORDS = re.compile(r'^\s*(?:template\s*<[^>]*>\s*)?(namespace|class|struct|union|enum|extern)\b')


def blank(text):
    """Replaces comments and string/char literals by spaces, keeping newlines."""
    out, i, n = [], 0, len(text)
    while i < n:
        c = text[i]
        if text.startswith('//', i):
            j = text.find('\n', i)
            j = n if j < 0 else j
            out.append(' ' * (j - i)); i = j
        elif text.startswith('/*', i):
            j = text.find('*/', i + 2)
            j = n if j < 0 else j + 2
            out.append(re.sub(r'[^\n]', ' ', text[i:j])); i = j
        elif text.startswith('R"', i):
            m = re.match(r'R"([^(]*)\(', text[i:])
            end = text.find(')' + m.group(1) + '"', i) if m else -1
            j = n if end < 0 else end + len(m.group(1)) + 2
            out.append(re.sub(r'[^\n]', ' ', text[i:j])); i = j
        elif c in '"\'':
            if c == "'" and i > 0 and (text[i - 1].isalnum()):  # digit separator 1'000
                out.append(' '); i += 1; continue
            j = i + 1
            while j < n and text[j] != c:
                j += 2 if text[j] == '\\' else 1
            out.append(' ' * (min(j + 1, n) - i)); i = j + 1
        else:
            out.append(c); i += 1
    return ''.join(out)


def functions(path):
    text = blank(path.read_text(errors='replace'))
    stack, stmt_start, results = [], 0, []
    line = 1
    for i, c in enumerate(text):
        if c == '\n':
            line += 1
        elif c == '{':
            outer = not stack or stack[-1][0] == 'scope'
            stmt = text[stmt_start:i]
            if outer:
                if SCOPE_WORDS.match(stmt) or '(' not in stmt or '=' in stmt.split('(')[0]:
                    kind = 'scope' if SCOPE_WORDS.match(stmt) else ('block' if '(' in stmt else 'scope')
                else:
                    kind = 'function'
                name = re.findall(r'([~\w:]+)\s*\(', stmt)
                stack.append((kind, line, name[0] if name else '?'))
            else:
                stack.append(('block', line, ''))
            stmt_start = i + 1
        elif c == '}':
            if stack:
                kind, start, name = stack.pop()
                if kind == 'function':
                    results.append((line - start + 1, start, name))
            stmt_start = i + 1
        elif c == ';' and (not stack or stack[-1][0] == 'scope'):
            stmt_start = i + 1
        elif c == ':' and (not stack or stack[-1][0] == 'scope'):
            # access specifiers (public:) end a statement; '::' and initialiser lists do not
            if re.search(r'\b(public|private|protected|signals|slots)\s*$', text[stmt_start:i]):
                stmt_start = i + 1
    return results


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument('--max', type=int, default=80)
    ap.add_argument('paths', nargs='+')
    args = ap.parse_args()
    files = []
    for p in map(pathlib.Path, args.paths):
        files += sorted(p.rglob('*')) if p.is_dir() else [p]
    over = []
    for f in files:
        if f.suffix in ('.cpp', '.h', '.hpp') and f.is_file():
            over += [(n, f, s, name) for n, s, name in functions(f) if n > args.max]
    for n, f, s, name in sorted(over, reverse=True):
        print(f'{f}:{s}: {name} is {n} lines (limit {args.max})')
    return 1 if over else 0


if __name__ == '__main__':
    sys.exit(main())
