#!/usr/bin/env python3
"""Checks every #include "..." under the source tree against the layer map (tools/layers.txt).

    tools/check_layers.py [--map FILE] [ROOT]

Prints each forbidden include as FILE:LINE: "INCLUDE" -> LAYER (TARGET) and exits 1 if there
is any, 2 if the map is malformed, 0 otherwise.
"""
import os
import re
import sys

SOURCE = re.compile(r'\.(c|cc|cpp|h|hpp)$')
INCLUDE = re.compile(r'^\s*#\s*include\s*"([^"]+)"')


def read_map(path):
    roots, layers, allowed, private, allow = [], {}, {}, [], set()
    for n, raw in enumerate(open(path), 1):
        line = raw.split('#', 1)[0].split()
        if not line:
            continue
        kind, args = line[0], line[1:]
        if kind == 'roots':
            roots = args
        elif kind == 'layer' and args:
            dirs, _, may = ' '.join(args[1:]).partition(':')
            for d in dirs.split():
                layers[d.rstrip('/')] = args[0]
            allowed[args[0]] = set(may.split()) | {args[0]}
        elif kind == 'private':
            private += [d.rstrip('/') for d in args]
        elif kind == 'allow' and len(args) == 2:
            allow.add((args[0], args[1]))
        else:
            sys.exit(f'{path}:{n}: cannot read "{raw.strip()}"')
    return roots, layers, allowed, private, allow


def owner(path, dirs):
    """The longest of dirs that contains path, or None."""
    best = None
    for d in dirs:
        if (path == d or path.startswith(d + '/')) and (best is None or len(d) > len(best)):
            best = d
    return best


def main():
    args = sys.argv[1:]
    here = os.path.dirname(os.path.abspath(__file__))
    map_path = os.path.join(here, 'layers.txt')
    if args[:1] == ['--map']:
        map_path, args = args[1], args[2:]
    root = args[0] if args else os.path.dirname(here)
    roots, layers, allowed, private, allow = read_map(map_path)
    os.chdir(root)
    bad, checked = [], 0
    for top in sorted({d.split('/')[0] for d in layers}):
        for d, subdirs, files in os.walk(top):
            subdirs.sort()
            for f in sorted(files):
                if not SOURCE.search(f):
                    continue
                src = os.path.join(d, f)
                home = owner(src, layers)
                if home is None:
                    bad.append(f'{src}: in no layer of {map_path}')
                    continue
                layer = layers[home]
                for n, text in enumerate(open(src, errors='replace'), 1):
                    m = INCLUDE.match(text)
                    if not m:
                        continue
                    inc = m.group(1)
                    cands = [os.path.join(d, inc)] + [os.path.join(r, inc) for r in roots]
                    target = next((os.path.normpath(c) for c in cands if os.path.isfile(c)), None)
                    if target is None or (src, inc) in allow:
                        continue  # a system header spelt with quotes, or a listed exception
                    checked += 1
                    tdir = owner(target, layers)
                    tlayer = layers[tdir] if tdir else '(none)'
                    why = None
                    if '*' not in allowed[layer] and tlayer not in allowed[layer]:
                        why = f'layer {tlayer}, which {layer} may not include'
                    else:
                        p = owner(target, private)
                        if p and layer != 'tests' and not (src.startswith(p + '/')):
                            why = f'private to {p}'
                    if why:
                        bad.append(f'{src}:{n}: "{inc}" -> {tlayer} ({target}): {why}')
    for b in bad:
        print(b)
    print(f'check_layers: {checked} includes checked, {len(bad)} forbidden', file=sys.stderr)
    return 1 if bad else 0


if __name__ == '__main__':
    sys.exit(main())
