#!/usr/bin/env bash
# Fails, naming the files, when a C++ source of the project differs from what clang-format makes of it with the
# repository's .clang-format. Usage: check_format.sh SOURCE_DIR
set -euo pipefail
cd "$1"
command -v clang-format >/dev/null || { echo "clang-format is not installed (scripts/setup.sh installs it)" >&2; exit 1; }
mapfile -t files < <(find geometry mapping service clients proto tests \( -name node_modules -o -name 'build*' \) -prune \
  -o \( -name '*.cc' -o -name '*.h' \) -type f -print | sort)
drifted=()
for file in "${files[@]}"; do
  clang-format --dry-run --Werror "$file" >/dev/null 2>&1 || drifted+=("$file")
done
if [ "${#drifted[@]}" -gt 0 ]; then
  echo "not formatted as .clang-format says (run clang-format -i on them):" >&2
  printf '  %s\n' "${drifted[@]}" >&2
  exit 1
fi
echo "${#files[@]} C++ files formatted as .clang-format says"
