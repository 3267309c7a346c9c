#!/usr/bin/env bash
# The PAX chain at an earlier commit and now, alternating in one run (this machine's noise is
# larger than most differences worth knowing, so only a side-by-side comparison tells).
#
#   bench/pax_chain_ab.sh COMMIT [ROUNDS]
#
# COMMIT runs from a temporary worktree with PYTHONPATH on its python/, this checkout's venv
# and this checkout's plugin jar (so it compares the Python side and the bridge, not the Java).
set -euo pipefail
cd "$(dirname "$0")/.."
before=$1 rounds=${2:-3}
tree=$(mktemp -d)
trap 'git worktree remove --force "$tree" >/dev/null 2>&1 || true' EXIT
git worktree add -q --detach "$tree" "$before"
ln -s "$PWD/.venv" "$tree/.venv"
mkdir -p "$tree/java/pax-plugins/target"
cp java/pax-plugins/target/pax-plugins.jar "$tree/java/pax-plugins/target/"
now=$(git rev-parse --short HEAD)
for round in $(seq "$rounds"); do
  echo "=== before ($before), round $round"
  (cd "$tree" && PYTHONPATH="$tree/python" "$OLDPWD/.venv/bin/python" bench/pax_chain.py --calls 1000 | tail -6)
  echo "=== now ($now), round $round"
  .venv/bin/python bench/pax_chain.py --calls 1000 | tail -6
done
