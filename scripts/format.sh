#!/usr/bin/env bash
# Formats the project's C++ sources with the repository's .clang-format (clang-format 14,
# Debian's clang-format-14). Usage:
#   scripts/format.sh           rewrite every tracked .cc/.h in place
#   scripts/format.sh --check   change nothing; list the files that are not formatted and
#                               exit 1 if there is any (CI's format stage)
# Third-party and generated code is not ours to format: data/ and the fuzz corpora hold
# none, fastddsgen writes its code into the build folder.
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."

format="${CLANG_FORMAT:-clang-format-14}"
if ! command -v "$format" >/dev/null 2>&1; then
  echo "format: $format not found (Debian: apt-get install clang-format-14)" >&2
  exit 2
fi

mapfile -t files < <(git ls-files '*.cc' '*.h' | grep -v -E '^(data|tests/fuzz/corpus)/')
if [ "${1:-}" == "--check" ]; then
  # One clang-format process for all files; each unformatted place is reported as
  # "FILE:LINE:COL: error: code should be clang-formatted".
  mapfile -t bad < <("$format" --dry-run --Werror "${files[@]}" 2>&1 |
    sed -n -E 's/^([^:]+):[0-9]+:[0-9]+: error: code should be clang-formatted.*/\1/p' | sort -u)
  if [ "${#bad[@]}" -gt 0 ]; then
    echo "format: ${#bad[@]} of ${#files[@]} files are not formatted (bash scripts/format.sh fixes them):" >&2
    printf '  %s\n' "${bad[@]}" >&2
    for f in "${bad[@]:0:3}"; do "$format" "$f" | diff -u "$f" - | head -n 20 >&2 || true; done
    exit 1
  fi
  echo "format: all ${#files[@]} files formatted"
else
  "$format" -i "${files[@]}"
  echo "format: formatted ${#files[@]} files"
fi
