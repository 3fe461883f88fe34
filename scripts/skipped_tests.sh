#!/usr/bin/env bash
# Counts the tests a ctest run skipped, from its JUnit file (ctest --output-junit FILE), and says why.
#   scripts/skipped_tests.sh JUNIT_XML
# The tests are GoogleTest cases registered by gtest_discover_tests, which gives each one
# SKIP_REGULAR_EXPRESSION "[  SKIPPED ]": a GTEST_SKIP() is a ctest "Skipped" test (status
# "notrun" in the JUnit file, not a pass), and its reason is the line after "<file>:<line>: Skipped"
# in the test's output. DISABLED_ tests are counted apart (status "disabled").
# Prints one line per skipped test ("  <test>: <reason>") and a summary line
#   tests skipped: N (M for a missing vocabulary or photographs, U without a reason in their
#   output), disabled: D, of T
# Exit status: 0; with CI=true, 1 when any test was skipped for a missing vocabulary or missing
# photographs (a broken environment must not pass as green), a skipped test's output holds no
# reason (it cannot be told apart), or JUNIT_XML is missing or lists no test at all; 2 on a usage
# error. Other skips are listed and counted, not fatal.
set -euo pipefail

if [ $# -ne 1 ]; then
  echo "usage: scripts/skipped_tests.sh JUNIT_XML" >&2
  exit 2
fi
junit=$1
ci=false
[ "${CI:-}" = true ] && ci=true

if [ ! -s "$junit" ]; then
  echo "skipped_tests: $junit: missing or empty (no ctest --output-junit results); skipped tests unknown" >&2
  [ "$ci" = true ] && exit 1
  exit 0
fi

# "<status>\t<name>\t<reason>" per test case that did not run; the reason is XML-unescaped.
cases=$(awk '
  function unescape(s) {
    gsub(/&lt;/, "<", s); gsub(/&gt;/, ">", s); gsub(/&quot;/, "\"", s); gsub(/&apos;/, "\047", s)
    gsub(/&amp;/, "\\&", s)
    return s
  }
  function attribute(line, key,    rest) {
    if (!match(line, key "=\"[^\"]*\"")) return ""
    rest = substr(line, RSTART + length(key) + 2, RLENGTH - length(key) - 3)
    return rest
  }
  /<testcase / {
    name = unescape(attribute($0, "name")); status = attribute($0, "status"); reason = ""; after_skip = 0
    in_case = 1; next
  }
  in_case && /<skipped message=/ && reason == "" { fallback = unescape(attribute($0, "message")) }
  in_case && after_skip { reason = unescape($0); after_skip = 0 }
  in_case && reason == "" && /: Skipped$/ { after_skip = 1 }
  /<\/testcase>/ {
    if (status == "notrun" || status == "disabled") {
      if (status == "disabled") reason = "disabled"
      else if (reason == "") reason = "(no reason in its output; ctest: " (fallback == "" ? "not run" : fallback) ")"
      printf "%s\t%s\t%s\n", status, name, reason
    }
    in_case = 0; fallback = ""
  }
' "$junit")

total=$(grep -c '<testcase ' "$junit" || true)
skipped=0
environment=0
unexplained=0
disabled=0
while IFS=$'\t' read -r status name reason; do
  [ -z "$status" ] && continue
  if [ "$status" = disabled ]; then
    disabled=$((disabled + 1))
    continue
  fi
  skipped=$((skipped + 1))
  mark=""
  if [[ ${reason,,} =~ vocabulary|photograph|wallpaper ]]; then
    environment=$((environment + 1))
    mark=" [environment]"
  elif [[ $reason == "(no reason in its output"* ]]; then
    unexplained=$((unexplained + 1))
    mark=" [unexplained]"
  fi
  echo "  $name: $reason$mark"
done <<<"$cases"

echo "tests skipped: $skipped ($environment for a missing vocabulary or photographs, $unexplained without a" \
  "reason in their output), disabled: $disabled, of $total"
if [ "$ci" = true ]; then
  if [ "$total" -eq 0 ]; then
    echo "skipped_tests: CI=true and $junit lists no test" >&2
    exit 1
  fi
  if [ "$environment" -gt 0 ]; then
    echo "skipped_tests: CI=true and $environment test(s) skipped for a missing vocabulary or photographs" \
      "(scripts/setup.sh installs the photographs; the vocabulary is Vocabulary/ltlo_orb_k10_L5.bin)" >&2
    exit 1
  fi
  if [ "$unexplained" -gt 0 ]; then  # the reason may have been a missing vocabulary: not green
    echo "skipped_tests: CI=true and $unexplained skipped test(s) without a reason in their output" >&2
    exit 1
  fi
fi
exit 0
