#!/usr/bin/env bash
# `make format` leaves the tree unchanged: every tracked C++ file is as clang-format writes it.
# Skips (exit 77) outside a git checkout or without clang-format.
set -euo pipefail
cd "$1"
command -v clang-format >/dev/null || { echo "clang-format not installed: skipped"; exit 77; }
git rev-parse --is-inside-work-tree >/dev/null 2>&1 || { echo "not a git checkout: skipped"; exit 77; }
git ls-files -z --cached --others --exclude-standard '*.cpp' '*.h' | xargs -0 clang-format --dry-run -Werror
echo "$(git ls-files --cached --others --exclude-standard '*.cpp' '*.h' | wc -l) files formatted as .clang-format says"
