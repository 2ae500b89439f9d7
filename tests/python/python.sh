#!/usr/bin/env bash
# The Python package as a user gets it: `pip install ./python` (maturin builds the wheel) into a fresh virtual
# environment, the pytest suite against the `simnet` binary, and the quickstart notebook executed with nbclient.
set -euo pipefail
cd "$(dirname "$0")/../.."

# The command line the tests compare the package with (SIMNET_BIN: one built already).
BIN=${SIMNET_BIN:-$PWD/target/debug/simnet}
if [ -z "${SIMNET_BIN:-}" ]; then
  cargo build --locked -q
fi
VENV=target/py-venv
rm -rf "$VENV"
python3 -m venv "$VENV"
PY="$VENV/bin/python"
"$PY" -m pip install -q --disable-pip-version-check --upgrade pip
start=$(date +%s)
"$PY" -m pip install -q --disable-pip-version-check ./python
echo "pip install ./python: $(($(date +%s) - start)) s (the wheel built in release mode)"
"$PY" -m pip install -q --disable-pip-version-check pytest pyarrow nbclient nbformat ipykernel matplotlib vqf

# The check of the issue that asked for the package, from outside the source tree.
(cd "$VENV" && bin/python -c "import simnet; print(simnet.run('ring3', loss=0.2).nodes)")

SIMNET_BIN="$BIN" "$PY" -m pytest -q python/tests

MPLBACKEND=Agg "$PY" - <<'PY'
import nbclient, nbformat
path = "python/examples/quickstart.ipynb"
nb = nbformat.read(path, as_version=4)
nbclient.NotebookClient(nb, timeout=900, kernel_name="python3", resources={"metadata": {"path": "python/examples"}}).execute()
print(f"{path}: {len(nb.cells)} cells executed")
PY
