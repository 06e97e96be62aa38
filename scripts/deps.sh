#!/usr/bin/env bash
# Installs what palpa needs to build and test, each thing only when it is missing.
#   scripts/deps.sh            the Rust toolchain (and Debian packages for it)
#   scripts/deps.sh --gpu      plus Mesa's software Vulkan driver, libudev and Xvfb
#   scripts/deps.sh --cluster  plus Slurm (slurmctld, slurmd, the client) and munge, for
#                              the single-node cluster the Slurm test starts
# Safe to run repeatedly; does nothing when everything is present.
set -euo pipefail

RUST_MIN="1.95"
# Packages every build needs (a C compiler for -sys crates, TLS for rustup).
APT_BASE=(ca-certificates curl gcc libc6-dev pkg-config)
# Packages the GPU, gamepad and window tests need (software Vulkan: lavapipe).
APT_GPU=(mesa-vulkan-drivers libvulkan1 libudev-dev xvfb xauth)

# Packages the Slurm test needs (a single-node cluster run as root).
APT_CLUSTER=(slurmctld slurmd slurm-client munge)

want=("${APT_BASE[@]}")
for flag in "$@"; do
  case "$flag" in
    --gpu) want+=("${APT_GPU[@]}") ;;
    --cluster) want+=("${APT_CLUSTER[@]}") ;;
    *) echo "deps.sh: unknown flag $flag (expected --gpu, --cluster)" >&2; exit 2 ;;
  esac
done

missing=()
if command -v dpkg-query >/dev/null 2>&1; then
  for p in "${want[@]}"; do
    dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
  done
fi
if ((${#missing[@]})); then
  echo "palpa: installing Debian packages: ${missing[*]}" >&2
  sudo_cmd=()
  [[ $(id -u) -ne 0 ]] && sudo_cmd=(sudo)
  "${sudo_cmd[@]}" apt-get update -qq
  DEBIAN_FRONTEND=noninteractive "${sudo_cmd[@]}" apt-get install -y -qq --no-install-recommends "${missing[@]}"
fi

# Rust: rustup's toolchain in ~/.cargo, installed only if cargo is absent or too old.
[[ -f "$HOME/.cargo/env" ]] && source "$HOME/.cargo/env"
version_ok() {
  local have
  have=$(cargo --version 2>/dev/null | awk '{print $2}') || return 1
  [[ -n "$have" ]] && [[ "$(printf '%s\n%s\n' "$RUST_MIN" "$have" | sort -V | head -1)" == "$RUST_MIN" ]]
}
if ! version_ok; then
  if command -v rustup >/dev/null 2>&1; then
    rustup toolchain install stable --profile minimal -c rustfmt,clippy
    rustup default stable
  else
    echo "palpa: installing Rust (rustup, stable toolchain)" >&2
    curl --proto '=https' --tlsv1.2 -sSf https://sh.rustup.rs | sh -s -- -y --profile minimal -c rustfmt,clippy
    source "$HOME/.cargo/env"
  fi
fi
version_ok || { echo "palpa: need cargo ≥ $RUST_MIN, found: $(cargo --version 2>&1)" >&2; exit 1; }
