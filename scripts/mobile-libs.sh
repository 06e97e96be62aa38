#!/usr/bin/env bash
# Builds the app as a static library for each mobile target that is installed here
# (a static library needs no platform linker or SDK) and prints its size, raw and with
# the debug sections stripped. The library is the app and the on-line evaluator only:
# built with --no-default-features, it holds no command line (src/cli/, clap).
#
#   scripts/mobile-libs.sh [TARGET ..]   default: aarch64-linux-android aarch64-apple-ios
#                                        aarch64-apple-ios-sim
#
# Output: target/TARGET/release/libpalpa_app.a, and a line per target:
#   TARGET  raw MB  stripped MB
# Stripping uses llvm-strip (GNU strip cannot read aarch64 Mach-O objects).
#
# For Android it also links the shared library the APK would carry, to measure it:
# ld.lld, the way rustc links a cdylib (only android_main and ANativeActivity_onCreate
# exported, unreferenced sections dropped), without the NDK's sysroot: bionic's
# symbols stay undefined for the device's loader. The size is what ships; the file
# itself is not for a device (scripts/android-apk.sh links the real one with the NDK).
set -euo pipefail
cd "$(dirname "$0")/.."
targets=("$@")
[ ${#targets[@]} -gt 0 ] || targets=(aarch64-linux-android aarch64-apple-ios aarch64-apple-ios-sim)
installed="$(rustup target list --installed 2>/dev/null || true)"
strip_tool="$(command -v llvm-strip || true)"
built=0
mb() { awk -v b="$1" 'BEGIN { printf "%.1f", b / 1000000 }'; }
for t in "${targets[@]}"; do
  if ! grep -qx "$t" <<<"$installed"; then
    echo "mobile-libs.sh: skipping $t (not installed; 'rustup target add $t')"
    continue
  fi
  cargo rustc --locked --release -q -p palpa-app --lib --no-default-features \
    --target "$t" --crate-type staticlib
  lib="target/$t/release/libpalpa_app.a"
  raw=$(stat -c %s "$lib")
  if [ -n "$strip_tool" ]; then
    "$strip_tool" --strip-debug -o "$lib.stripped" "$lib"
    stripped=$(stat -c %s "$lib.stripped")
    printf '%-24s raw %7s MB  stripped %7s MB\n' "$t" "$(mb "$raw")" "$(mb "$stripped")"
  else
    printf '%-24s raw %7s MB  (no llvm-strip: apt install llvm)\n' "$t" "$(mb "$raw")"
  fi
  if [ "$t" = aarch64-linux-android ] && command -v ld.lld >/dev/null && [ -n "$strip_tool" ]; then
    so="target/$t/release/libpalpa_app.size-check.so"
    map="$(mktemp)"
    printf '{ global: android_main; ANativeActivity_onCreate; local: *; };\n' >"$map"
    ld.lld -m aarch64linux -shared --gc-sections --version-script="$map" -z max-page-size=16384 \
      --undefined=ANativeActivity_onCreate --undefined=android_main -soname libpalpa_app.so \
      -o "$so" "$lib"
    "$strip_tool" --strip-unneeded "$so"
    rm -f "$map"
    printf '%-24s linked libpalpa_app.so, stripped: %s MB (goal: 25 MB)\n' "$t" "$(mb "$(stat -c %s "$so")")"
  fi
  built=$((built + 1))
done
echo "mobile-libs.sh: $built static librar$([ $built = 1 ] && echo y || echo ies) built"
