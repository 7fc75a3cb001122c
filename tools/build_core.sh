#!/usr/bin/env bash
# Rebuild the compiled core of an editable install after a change in csrc/ (pip install
# -e . builds it once; this reruns only the C++ build and copies the module in place).
# Usage: tools/build_core.sh BUILD_DIR  (the folder given to pip as -C build-dir=...)
set -euo pipefail
build="${1:?usage: tools/build_core.sh BUILD_DIR}"
cmake --build "$build"
site="$(python -c 'import sysconfig; print(sysconfig.get_paths()["platlib"])')"
for so in "$build"/_ext*.so; do  # a new file, renamed over the old: a running process keeps its copy
    cp "$so" "$site/continuum_mhe/_core/.$(basename "$so").tmp"
    mv -f "$site/continuum_mhe/_core/.$(basename "$so").tmp" "$site/continuum_mhe/_core/$(basename "$so")"
done
