#!/usr/bin/env bash
# Create .venv-bench (the peers' own virtual environment) and install
# benchmarks/requirements-peers.txt into it. Idempotent: when the environment already
# holds exactly these requirements it returns at once.
#
#   bash benchmarks/setup_peers.sh            # from the repository root (or anywhere)
#   PYTHON=python3.11 VENV=/path/to/venv bash benchmarks/setup_peers.sh
set -euo pipefail

here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
root="$(cd "$here/.." && pwd)"
venv="${VENV:-$root/.venv-bench}"
python="${PYTHON:-python3}"
req="$here/requirements-peers.txt"
stamp="$venv/.requirements-peers.sha256"

want="$(sha256sum "$req" | cut -d' ' -f1)"
if [[ -x "$venv/bin/python" && -f "$stamp" && "$(cat "$stamp")" == "$want" ]]; then
    echo "setup_peers: $venv is up to date"
    exit 0
fi

if [[ ! -x "$venv/bin/python" ]]; then
    echo "setup_peers: creating $venv with $("$python" --version 2>&1)"
    "$python" -m venv "$venv"
fi
echo "setup_peers: installing $(grep -cv '^\s*\(#\|$\)' "$req") pinned packages into $venv"
"$venv/bin/python" -m pip install --quiet --disable-pip-version-check -r "$req"
"$venv/bin/python" -c "import meent, grcwa, fmmax; print('setup_peers: meent', meent.__version__, '/ grcwa', grcwa.__version__, '/ fmmax', fmmax.__version__)"
echo "$want" > "$stamp"
