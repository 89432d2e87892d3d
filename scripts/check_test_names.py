#!/usr/bin/env python3
"""File-local names of the test files, checked for clashes within each test suite.

    scripts/check_test_names.py [REPO]   exit 1 and list every name that two test files of one suite define at file
                                         scope, exit 0 when there is none.

The test files of a suite compile in unity batches (cmake/VmsimModule.cmake): a helper, constant, type or macro that
two files define would clash, or worse, a call in one file would silently bind to the other file's overload, when
the two land in one batch, which depends on how many files come before them. This finds such pairs before a batch
does. It reads definitions written from column 0 (the project's style: namespaces do not indent), so it is a lint,
not a parser; -DVMSIM_TEST_UNITY_BATCH=0 compiles each suite as one file, the full check. ctest runs it
(test `test_names`).
"""
import collections
import os
import re
import sys

# Definitions from column 0: a function (its name before '(' on a line that does not end in ';'), a variable with an
# initialiser, a type, a macro, a type alias.
FUNCTION = re.compile(r'^(?:template\s*<[^>]*>\s*)?(?:static\s+|inline\s+|constexpr\s+)*'
                      r'[A-Za-z_][\w:<>,\s\*&]*?[\s\*&]([A-Za-z_]\w*)\s*\(')
VARIABLE = re.compile(r'^(?:static\s+|inline\s+)*(?:const|constexpr)\s+[\w:<>,\s\*&]+?\b([A-Za-z_]\w*)\s*(?:=|\{|\[)')
TYPE = re.compile(r'^(?:struct|class|enum\s+class|enum|union)\s+([A-Za-z_]\w*)\b(?!\s*;)')
MACRO = re.compile(r'^#\s*define\s+([A-Za-z_]\w*)')
ALIAS = re.compile(r'^using\s+([A-Za-z_]\w*)\s*=')
NOT_A_DEFINITION = re.compile(r'^(?:TEST|TEST_F|TEST_P|TYPED_TEST|INSTANTIATE|return|else|if|for|while|using\s+namespace)\b')


def definitions(path):
    """(name, kind, text) of each file-scope definition; a macro's text is its whole definition."""
    found = []
    with open(path, encoding='utf-8', errors='replace') as f:
        lines = f.read().split('\n')
    for i, line in enumerate(lines):
        if not line or line[0] in ' \t/}{*' or NOT_A_DEFINITION.match(line):
            continue
        m = MACRO.match(line)
        if m:
            text = line
            j = i
            while text.endswith('\\') and j + 1 < len(lines):
                j += 1
                text = text[:-1] + lines[j]
            found.append((m.group(1), 'macro', ' '.join(text.split())))
            continue
        if line.startswith('#'):
            continue
        for kind, pattern in (('type', TYPE), ('alias', ALIAS), ('variable', VARIABLE)):
            m = pattern.match(line)
            if m:
                found.append((m.group(1), kind, ''))
                break
        else:
            m = FUNCTION.match(line)
            if m and not line.rstrip().endswith(';') and m.group(1) not in ('operator',):
                found.append((m.group(1), 'function', ''))
    return found


def main():
    repo = sys.argv[1] if len(sys.argv) > 1 else os.path.join(os.path.dirname(os.path.abspath(__file__)), '..')
    tests = os.path.join(repo, 'tests')
    # The suites whose files compile together: vmsim_test_suite(NAME ...) in tests/CMakeLists.txt (one executable per
    # folder); the other folders build one executable per file.
    with open(os.path.join(tests, 'CMakeLists.txt'), encoding='utf-8') as f:
        suites = re.findall(r'^vmsim_test_suite\((\w+)', f.read(), flags=re.M)
    clashes = []
    for suite in suites:
        folder = os.path.join(tests, suite)
        by_name = collections.defaultdict(list)
        for name in sorted(os.listdir(folder)):
            if name.endswith('_test.cpp'):
                for ident, kind, text in definitions(os.path.join(folder, name)):
                    by_name[ident].append((name, kind, text))
        for ident, where in sorted(by_name.items()):
            files = sorted({w[0] for w in where})
            if len(files) < 2:
                continue
            # The same macro, token for token, may be defined twice (a repeated identical #define is legal).
            if all(w[1] == 'macro' for w in where) and len({w[2] for w in where}) == 1:
                continue
            clashes.append(f'tests/{suite}: {ident} ({where[0][1]}) is defined in {", ".join(files)}')
    for c in clashes:
        print(c)
    if clashes:
        print(f'{len(clashes)} file-scope names defined in more than one test file of a suite: give each a distinct '
              'name or move the shared one into the suite\'s test-support header')
        return 1
    return 0


if __name__ == '__main__':
    sys.exit(main())
