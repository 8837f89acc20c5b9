#!/usr/bin/env bash
# Install EPyMARL at a pinned commit OUTSIDE this repository and its Python requirements into the CURRENT venv.
#
#   bash benchmarks/epymarl/install.sh [--from DIR] [--dest DIR] [--commit HASH]
#
#   --from DIR   a local clone or bare mirror of uoe-agents/epymarl to clone from (default: clone from GitHub)
#   --dest DIR   where the EPyMARL checkout goes (default: ~/.cache/smac-hard-gym/epymarl)
#   --commit H   the commit to check out (default: the pinned one below)
#
# Installs only what EPyMARL imports on the QMIX/MAPPO + sc2 path: sacred, einops (imported by its learner registry),
# PyYAML, cloudpickle, gymnasium (the last three are usually there already). It does NOT install oxwhirl's smac
# (smac-hard-gym's examples/epymarl/smac_shim provides `smac`), pysc2, or a second torch: torch must already be in
# the venv (smac-hard-gym's own install brings the CPU build you chose).
set -euo pipefail

PINNED=cbc38c09588064eab978501d0f12c2cf58fa7fc2   # uoe-agents/epymarl main, 2024-09-24 ("Update README.md")
FROM=""
DEST="${HOME}/.cache/smac-hard-gym/epymarl"
COMMIT="$PINNED"
while [ $# -gt 0 ]; do
  case "$1" in
    --from) FROM="$2"; shift 2 ;;
    --dest) DEST="$2"; shift 2 ;;
    --commit) COMMIT="$2"; shift 2 ;;
    -h|--help) sed -n 2,14p "$0"; exit 0 ;;
    *) echo "unknown argument: $1" >&2; exit 2 ;;
  esac
done
SRC="${FROM:-https://github.com/uoe-agents/epymarl.git}"

if [ -d "$DEST/.git" ]; then
  echo "EPyMARL checkout exists at $DEST; fetching from $SRC if the commit is missing"
  git -C "$DEST" cat-file -e "${COMMIT}^{commit}" 2>/dev/null || git -C "$DEST" fetch "$SRC"
else
  mkdir -p "$(dirname "$DEST")"
  git clone --no-checkout "$SRC" "$DEST"
fi
git -C "$DEST" -c advice.detachedHead=false checkout --force "$COMMIT"
echo "EPyMARL at $(git -C "$DEST" rev-parse HEAD) in $DEST"

python - <<'PY'
import sys
try:
    import torch
except ImportError:
    sys.exit("torch is not installed in this venv: install smac-hard-gym (and its torch) first; this script adds no torch")
print("torch", torch.__version__, "(kept)")
PY
# sacred 0.8.x imports pkg_resources, which setuptools 81+ no longer ships
python -m pip install "sacred>=0.8.5" einops pyyaml cloudpickle "gymnasium>=1.0" "setuptools<81"
python -c "import smac" 2>/dev/null && python -c "import smac, sys; print('WARNING: a smac package is installed (' + smac.__file__ + '); the smac_shim on PYTHONPATH must come first')" || true
echo "done. Run benchmarks with:  python benchmarks/epymarl/run_reference.py --epymarl $DEST ..."
