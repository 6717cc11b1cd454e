#!/usr/bin/env bash
# Optional peer comparison (not in CI): installs mitsuba 3.9.1 + mitransient 1.3.1 into a venv,
# Debian's libllvm19 for Dr.Jit's LLVM backend (LLVM 15 aborts), builds dtr, and runs the script.
set -euo pipefail
cd "$(dirname "$0")/../.."
apt-get install -y -qq libllvm19 >/dev/null
[ -x bench-out/peer-venv/bin/python ] || python3 -m venv bench-out/peer-venv
bench-out/peer-venv/bin/pip install -q mitsuba==3.9.1 mitransient==1.3.1 numpy
cargo build --release -q
export DRJIT_LIBLLVM_PATH=$(ls /usr/lib/*-linux-gnu/libLLVM-19.so* | head -n 1)
exec bench-out/peer-venv/bin/python benches/peer/compare_mitransient.py "$@"
