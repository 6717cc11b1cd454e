#!/usr/bin/env bash
# Optional peer comparison (not in CI): installs mitsuba 3.9.1 + mitransient 1.3.1 into a venv,
# Debian's libllvm19 for Dr.Jit's LLVM backend (LLVM 15 aborts), builds dtr, and runs the script:
# compare_mitransient.py (the Cornell box), or with the argument `nlos` compare_nlos.py (a relay wall).
# PEER_NEE_FIX=1 runs it with a copy of the venv (bench-out/peer-venv-neefix) whose mitransient
# places next-event segments taken through a refraction at the far side's index
# (nee_opl_fix.py; BENCHMARKS.md, "Rough dielectrics against mitransient's roughdielectric").
set -euo pipefail
cd "$(dirname "$0")/../.."
apt-get install -y -qq libllvm19 >/dev/null
[ -x bench-out/peer-venv/bin/python ] || python3 -m venv bench-out/peer-venv
bench-out/peer-venv/bin/pip install -q mitsuba==3.9.1 mitransient==1.3.1 numpy
cargo build --release -q
export DRJIT_LIBLLVM_PATH=$(ls /usr/lib/*-linux-gnu/libLLVM-19.so* | head -n 1)
venv=bench-out/peer-venv
if [ "${PEER_NEE_FIX:-0}" = 1 ]; then
  [ -x bench-out/peer-venv-neefix/bin/python ] || cp -a bench-out/peer-venv bench-out/peer-venv-neefix
  bench-out/peer-venv-neefix/bin/python benches/peer/nee_opl_fix.py bench-out/peer-venv-neefix
  venv=bench-out/peer-venv-neefix
fi
# `run.sh nlos`: the relay-wall comparison (compare_nlos.py); `run.sh nlos-diagonal`: whether
# each renderer's exhaustive capture holds its confocal one on the diagonal
# (nlos_exhaustive_diagonal.py); otherwise the Cornell box
if [ "${1:-}" = nlos-diagonal ]; then
  shift
  exec "$venv"/bin/python benches/peer/nlos_exhaustive_diagonal.py "$@"
fi
if [ "${1:-}" = nlos ]; then
  shift
  exec "$venv"/bin/python benches/peer/compare_nlos.py "$@"
fi
exec "$venv"/bin/python benches/peer/compare_mitransient.py "$@"
