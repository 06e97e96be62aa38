#!/usr/bin/env bash
# Xcode pre-build phase: builds palpa-app's static library for the SDK and
# architectures Xcode is building, into ../target/ios/$PLATFORM_NAME/libpalpa_app.a.
#   iphoneos        → aarch64-apple-ios
#   iphonesimulator → aarch64-apple-ios-sim (Apple silicon) and x86_64-apple-ios
#                     (Intel), joined by lipo
# Run by hand: PLATFORM_NAME=iphoneos ARCHS=arm64 CONFIGURATION=Release ios/build-rust.sh
set -euo pipefail
cd "$(dirname "$0")/.."
# Xcode runs build phases with a minimal PATH; rustup's cargo lives in ~/.cargo/bin.
export PATH="$HOME/.cargo/bin:$PATH"
platform="${PLATFORM_NAME:-iphoneos}"
profile=release
[ "${CONFIGURATION:-Release}" = Debug ] && profile=dev
out="target/ios/$platform"
mkdir -p "$out"
libs=()
for arch in ${ARCHS:-arm64}; do
  case "$platform:$arch" in
    iphoneos:arm64) t=aarch64-apple-ios ;;
    iphonesimulator:arm64) t=aarch64-apple-ios-sim ;;
    iphonesimulator:x86_64) t=x86_64-apple-ios ;;
    *) echo "build-rust.sh: no Rust target for $platform $arch" >&2; exit 1 ;;
  esac
  rustup target list --installed | grep -qx "$t" || rustup target add "$t"
  cargo rustc --locked --profile "$profile" -p palpa-app --lib --no-default-features \
    --target "$t" --crate-type staticlib
  dir=release
  [ "$profile" = dev ] && dir=debug
  libs+=("target/$t/$dir/libpalpa_app.a")
done
if [ ${#libs[@]} -eq 1 ]; then
  cp "${libs[0]}" "$out/libpalpa_app.a"
else
  lipo -create "${libs[@]}" -output "$out/libpalpa_app.a"
fi
echo "build-rust.sh: $out/libpalpa_app.a"
