# Sourced by the mitransient scripts (mitransient_check.sh, mitransient_draws.sh): Debian's
# libllvm19 (Debian 12's LLVM 15 crashes drjit) and the renderer's own venv, .venv-mitransient
# (mitransient 1.3.1, which brings mitsuba 3.9.1 and drjit 1.5.0). Run from the repo root.
if ! ls /usr/lib/x86_64-linux-gnu/libLLVM.so.19* >/dev/null 2>&1; then
    ${SUDO:-$(command -v sudo || true)} apt-get install -y libllvm19
fi
export DRJIT_LIBLLVM_PATH=${DRJIT_LIBLLVM_PATH:-$(ls /usr/lib/x86_64-linux-gnu/libLLVM.so.19* | head -1)}
if [ ! -x .venv-mitransient/bin/python ]; then
    python3 -m venv .venv-mitransient
    .venv-mitransient/bin/pip install -q mitransient==1.3.1 numpy trimesh
fi
