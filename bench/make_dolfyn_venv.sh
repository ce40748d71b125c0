#!/usr/bin/env bash
# Builds bench/.venv-dolfyn: the comparator for bench_pd0.py (dolfyn pins numpy < 2,
# so it cannot share the project's venv). Idempotent; gitignored.
set -euo pipefail
cd "$(dirname "$0")"
VENV=.venv-dolfyn
PYTHON=${PYTHON:-python3}
if [ ! -x "$VENV/bin/python" ] || ! "$VENV/bin/python" -c "import dolfyn" 2>/dev/null; then
    "$PYTHON" -m venv "$VENV"
    "$VENV/bin/python" -m pip install --quiet --upgrade pip
    "$VENV/bin/python" -m pip install --quiet "dolfyn==1.3.0" "numpy<2" "scipy<1.14"  # dolfyn 1.3 imports scipy.integrate.cumtrapz
fi
"$VENV/bin/python" -c "import dolfyn, numpy; print('dolfyn', dolfyn.__version__, 'numpy', numpy.__version__)"
