# Sourced by the test scripts: what a step does when a tool it needs is missing.
#   CI=true (exported by .ci/run): scripts/setup.sh installs every tool, so a missing one is a
#     broken set-up: the step fails (exit 1).
#   Elsewhere: the step is skipped, visibly: the reason on stderr and exit 77, which
#     scripts/test.sh lists as skipped at the end of the run.
# attekf_require <tag> <tool...>: attekf_missing unless every tool is on PATH.

attekf_in_ci() {
  case "${CI:-}" in
    1 | [Tt][Rr][Uu][Ee] | [Yy][Ee][Ss]) return 0 ;;
  esac
  return 1
}

# attekf_missing <tag> <reason>: fails (CI) or skips (exit 77) the step; does not return.
attekf_missing() {
  if attekf_in_ci; then
    echo "[$1] FAILED: $2 (CI=true: a missing tool fails the run; scripts/setup.sh installs it)" >&2
    exit 1
  fi
  echo "[$1] SKIPPED: $2 (scripts/setup.sh installs it)" >&2
  exit 77
}

attekf_require() {
  local tag="$1" tool
  shift
  for tool in "$@"; do
    command -v "$tool" >/dev/null 2>&1 || attekf_missing "$tag" "$tool not installed"
  done
}
