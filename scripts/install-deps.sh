#!/usr/bin/env bash
# Installs the Debian packages lucent needs to build and test, only those
# that are missing. Safe to run repeatedly.
set -euo pipefail

packages=(
  pkg-config
  clang            # the opencv crate generates its bindings with libclang
  libclang-dev
  libopencv-dev    # OpenCV 4.6 (calib/ links calib3d, imgproc, imgcodecs)
  libopencv-contrib-dev  # OpenCV's contrib modules: mcc (ColorChecker detection) and the dnn it needs
  rawtran-doc      # a real Canon EOS 30D CR2 (GPL-3+) for the RAW decoder tests, read from /usr/share/doc/rawtran/
  chromium         # headless browser: tests/pipeline.rs opens the run report (report/index.html) and screenshots it
  mold             # fast linker for the test binaries and doctests (scripts/cc-link; plain cc without it)
  slurm-wlm        # Slurm (slurmctld, slurmd, sbatch, squeue, sacct): tests/slurm.rs runs a one-node cluster on localhost
  munge            # Slurm's authentication daemon, started by tests/slurm.rs with a generated key
  python3          # `make python`: the Python module (python/) and its tests run in a project-local venv
  python3-venv
)

missing=()
for p in "${packages[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed"; then
    missing+=("$p")
  fi
done

if ((${#missing[@]})); then
  echo "Installing missing Debian packages: ${missing[*]}"
  SUDO=""
  if [ "$(id -u)" -ne 0 ]; then SUDO="sudo"; fi
  $SUDO apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}"
fi

if ! command -v cargo >/dev/null 2>&1; then
  echo "error: cargo (Rust toolchain) not found; install Rust from https://rustup.rs or Debian's cargo package" >&2
  exit 1
fi

# `make test` also runs `cargo fmt --check` and `cargo clippy`: add the
# components through rustup where the toolchain lacks them.
for component in rustfmt clippy; do
  subcommand=${component/rustfmt/fmt}
  if ! cargo "$subcommand" --version >/dev/null 2>&1; then
    if command -v rustup >/dev/null 2>&1; then
      echo "Adding the Rust component $component"
      rustup component add "$component"
    else
      echo "warning: cargo $subcommand not found and no rustup to add it (Debian: apt-get install ${component/clippy/rust-clippy})" >&2
    fi
  fi
done
