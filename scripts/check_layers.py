#!/usr/bin/env python3
"""The module layering of DESIGN.md, checked: a module includes only the modules it may depend on.

    scripts/check_layers.py [REPO]     exit 1 and list every include that reaches up a layer (or into an unknown
                                       module), exit 0 when the graph is layered.

ctest runs it (test `layering`), so `make test` fails on an include that reaches up.
"""
import os
import re
import sys

# Who may include whom: each module lists the modules below it that it may use. core depends on nothing.
ALLOWED = {
    'core': set(),
    'program': {'core'},
    'motion': {'core'},
    'drives': {'core'},
    'sysid': {'core', 'drives'},
    'methods': {'core', 'motion', 'drives', 'sysid'},
    'removal': {'core'},
    'metrology': {'core'},
    'render': {'core'},
    'sim': {'core', 'program', 'motion', 'drives', 'sysid', 'methods', 'removal', 'metrology'},
    'python': {'core', 'program', 'motion', 'drives', 'sysid', 'methods', 'removal', 'metrology', 'render', 'sim'},
    'app': {'core', 'program', 'motion', 'drives', 'sysid', 'methods', 'removal', 'metrology', 'render', 'sim'},
}
INCLUDE = re.compile(r'^\s*#\s*include\s+"([^"]+)"')


def check(repo):
    problems = []
    for module, allowed in ALLOWED.items():
        folder = os.path.join(repo, module)
        if not os.path.isdir(folder):
            continue
        for root, _, files in os.walk(folder):
            for name in sorted(files):
                if not name.endswith(('.hpp', '.cpp', '.inc', '.h')):
                    continue
                path = os.path.join(root, name)
                with open(path, encoding='utf-8') as f:
                    for lineno, line in enumerate(f, 1):
                        m = INCLUDE.match(line)
                        if not m or '/' not in m.group(1):
                            continue
                        target = m.group(1).split('/')[0]
                        if target == module:
                            continue
                        rel = os.path.relpath(path, repo)
                        if target not in ALLOWED:
                            problems.append(f'{rel}:{lineno}: includes "{m.group(1)}" from "{target}/", which is '
                                            f'not a module of the layout (DESIGN.md)')
                        elif target not in allowed:
                            problems.append(f'{rel}:{lineno}: {module}/ includes "{m.group(1)}", but {module}/ may '
                                            f'use only {", ".join(sorted(allowed)) or "no other module"}')
    return problems


def main():
    repo = sys.argv[1] if len(sys.argv) > 1 else os.path.join(os.path.dirname(__file__), '..')
    problems = check(os.path.abspath(repo))
    for p in problems:
        print(p)
    if problems:
        print(f'{len(problems)} include(s) reach up a layer or out of the layout', file=sys.stderr)
        return 1
    print('layering: every module includes only the modules below it')
    return 0


if __name__ == '__main__':
    sys.exit(main())
