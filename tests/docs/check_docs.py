#!/usr/bin/env python3
"""The documentation stays true to the repository: every file a document names exists, every
Markdown link and picture resolves, and README.md stays short (under 100 lines, no line over 200
characters). Run by ctest (DocsTest.*) from the repository root; prints each finding, exit 1 if any."""
import pathlib
import re
import sys

ROOT = pathlib.Path(sys.argv[1] if len(sys.argv) > 1 else ".").resolve()
DOCS = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md")), *sorted((ROOT / "Examples").glob("*/README.md"))]
# A code span naming a repository file: has a folder, ends in a source/doc extension, no placeholder.
FILE_SPAN = re.compile(r"`([A-Za-z0-9_./-]+/[A-Za-z0-9_.-]+\.(?:h|cc|md|py|sh|yaml|txt|bin|png))`")
LINK = re.compile(r"\]\(([^)#\s]+)(?:#[^)]*)?\)")
# Where a short path such as `mapping/local_window_ba.cc` or `core/change_gate.h` may live.
PREFIXES = ["", "src/", "include/ltlo/"]
# Files a run or a program writes, not files of the repository.
RUN_OUTPUTS = {"trajectory.txt", "keyframes.txt", "imu_biases.txt", "table.md", "report.md", "calib.yaml"}


def exists(doc, name):
    if (doc.parent / name).exists():
        return True
    return any((ROOT / (prefix + name)).exists() for prefix in PREFIXES)


def main():
    findings = []
    for doc in DOCS:
        text = doc.read_text(encoding="utf-8")
        rel = doc.relative_to(ROOT)
        for number, line in enumerate(text.splitlines(), start=1):
            for name in FILE_SPAN.findall(line):
                base = name.rsplit("/", 1)[-1]
                if base in RUN_OUTPUTS or name.startswith(("out/", "build/", "/", "RUN/", "OUT/", "DIR/", "SEQ/")):
                    continue
                if not exists(doc, name):
                    findings.append(f"{rel}:{number}: names `{name}`, which does not exist")
            for target in LINK.findall(line):
                if re.match(r"[a-z]+://", target):
                    continue
                if not (doc.parent / target).exists():
                    findings.append(f"{rel}:{number}: link to {target}, which does not exist")
    readme = (ROOT / "README.md").read_text(encoding="utf-8").splitlines()
    if len(readme) >= 100:
        findings.append(f"README.md: {len(readme)} lines (a newcomer's read: under 100)")
    for number, line in enumerate(readme, start=1):
        if len(line) > 200:
            findings.append(f"README.md:{number}: {len(line)} characters (at most 200)")
    for finding in findings:
        print(finding)
    print(f"check_docs: {len(DOCS)} documents, {len(findings)} findings")
    return 1 if findings else 0


if __name__ == "__main__":
    sys.exit(main())
