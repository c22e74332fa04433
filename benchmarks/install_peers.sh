#!/usr/bin/env bash
# Install the peer libraries of benchmarks/test_peers.py into a venv (default .venv):
#   benchmarks/install_peers.sh [VENV]
# Idempotent (pip skips what is already satisfied). jax, jaxlib and numpy are pinned to the
# versions already in the venv through a constraints file, so no peer can change them; the script
# checks them again at the end and fails if they moved. torch 2.13.0 (the CPU build on this
# machine's disk) is installed first and explicitly, so that no peer pulls a CUDA build.
# A peer that cannot be installed is reported and left out; its benchmarks then skip.
set -euo pipefail

VENV="${1:-.venv}"
PY="$VENV/bin/python"
if [ ! -x "$PY" ]; then
    echo "install_peers: no python at $PY (create the venv first: make test)" >&2
    exit 1
fi
PIP=("$PY" -m pip --disable-pip-version-check --quiet)

TORCH_VERSION=2.13.0
# Versions measured together on 2026-11-22 (Python 3.11, jax 0.10.2, numpy 2.4.6).
PEERS=(
    "pylinkage==1.3.0"
    "visual-kinematics==0.2.1"
    "roboticstoolbox-python==1.5.0"
    "pytorch-kinematics==0.10.0"
    "almond-pyroki==0.1.1"
)

versions() {
    "$PY" - <<'EOF'
from importlib.metadata import PackageNotFoundError, version

for name in ("jax", "jaxlib", "numpy"):
    try:
        print(f"{name}=={version(name)}")
    except PackageNotFoundError:
        pass
EOF
}

before="$(versions)"
constraints="$(mktemp)"
trap 'rm -f "$constraints"' EXIT
{ echo "$before"; echo "torch==$TORCH_VERSION"; } >"$constraints"
echo "install_peers: keeping $(echo "$before" | tr '\n' ' ')in $VENV"

# torch first, alone and exact: pip takes the CPU wheel from local disk.
have_torch="$("$PY" -c 'import importlib.metadata as m; print(m.version("torch"))' 2>/dev/null || true)"
if [ "${have_torch%%+*}" != "$TORCH_VERSION" ]; then
    "${PIP[@]}" install -c "$constraints" "torch==$TORCH_VERSION"
fi

failed=()
for peer in "${PEERS[@]}"; do
    if ! "${PIP[@]}" install -c "$constraints" "$peer"; then
        echo "install_peers: could not install $peer; its benchmarks will skip" >&2
        failed+=("$peer")
    fi
done

after="$(versions)"
if [ "$before" != "$after" ]; then
    echo "install_peers: jax/jaxlib/numpy changed!" >&2
    echo "before: $before" >&2
    echo "after:  $after" >&2
    exit 1
fi
echo "install_peers: done; $(echo "$after" | tr '\n' ' ')unchanged; torch $("$PY" -c 'import torch; print(torch.__version__)')"
if [ "${#failed[@]}" -gt 0 ]; then
    echo "install_peers: not installed: ${failed[*]}" >&2
fi
