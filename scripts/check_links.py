#!/usr/bin/env python3
"""Checks the relative links of README.md and docs/*.md: the file exists, and an anchor
(#heading) matches a heading of that file as GitHub names it. Prints each broken link; exit 1
when there is one. Usage: scripts/check_links.py [FILE.md...]"""
import glob
import os
import re
import sys


def anchors(path):
    """GitHub's heading anchors: lower case, punctuation dropped, spaces to hyphens."""
    names, seen = set(), {}
    in_code = False
    with open(path) as f:
        for line in f:
            if line.startswith("```"):
                in_code = not in_code
            if in_code or not re.match(r"#{1,6} ", line):
                continue
            text = re.sub(r"`", "", line.lstrip("#").strip()).lower()
            slug = re.sub(r"[^\w\- ]", "", text).replace(" ", "-")
            n = seen.get(slug, 0)
            seen[slug] = n + 1
            names.add(slug if n == 0 else f"{slug}-{n}")
    return names


def main():
    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    files = sys.argv[1:] or [os.path.join(root, "README.md")] + sorted(
        glob.glob(os.path.join(root, "docs", "*.md")))
    broken = 0
    for path in files:
        text = open(path).read()
        text = re.sub(r"```.*?```", "", text, flags=re.S)
        for target in re.findall(r"\]\(([^)\s]+)\)", text):
            if re.match(r"[a-z]+:", target):
                continue
            file, _, anchor = target.partition("#")
            dest = os.path.normpath(os.path.join(os.path.dirname(path), file)) if file else path
            if not os.path.exists(dest):
                print(f"{os.path.relpath(path, root)}: {target}: no such file")
                broken += 1
            elif anchor and dest.endswith(".md") and anchor not in anchors(dest):
                print(f"{os.path.relpath(path, root)}: {target}: no such heading")
                broken += 1
    sys.exit(1 if broken else 0)


if __name__ == "__main__":
    main()
