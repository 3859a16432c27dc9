#!/usr/bin/env bash
# clang-format (check mode) on all C, cppcheck on the firmware and simulator,
# ruff on the Python. Generated files are listed in .lintignore.
set -euo pipefail
cd "$(dirname "$0")/.."
ignore=$(grep -v '^#' .lintignore 2>/dev/null | sed '/^$/d' || true)
c_files=$(git ls-files -co --exclude-standard -- '*.c' '*.h' | grep -v -F -x -f <(echo "${ignore:-/nonexistent}") || true)
echo "lint: clang-format on $(echo "$c_files" | wc -w) files"
clang-format --dry-run --Werror $c_files
echo "lint: cppcheck"
cppcheck --quiet --error-exitcode=1 --enable=warning,portability,performance \
  --std=c99 --inline-suppr --suppress=missingIncludeSystem --suppress=shiftTooManyBitsSigned \
  -Ifirmware/core -Ifirmware/hal -Ifirmware \
  firmware hil_sim
echo "lint: ruff"
.venv/bin/ruff check host_tools tests
.venv/bin/ruff format --check host_tools tests
echo "lint: clean"
