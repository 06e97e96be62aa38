#!/usr/bin/env bash
# Builds the Android package target/android/palpa.apk (arm64-v8a, debug-signed):
# a NativeActivity with no Java code whose app is libpalpa_app.so (android_main).
#
#   scripts/android-apk.sh            build and sign the APK
#   ANDROID_NDK_HOME=/opt/android-ndk-r26d scripts/android-apk.sh
#
# Steps, each checked before the next:
#   1. tools: aapt, zipalign, apksigner (Debian packages, installed when missing) and
#      the platform's resource table: $ANDROID_PLATFORM_RES (an android.jar of API 26+
#      or a framework-res.apk), else Debian's android-framework-res;
#   2. the manifest and resources (android/) compiled into the package;
#   3. libpalpa_app.so linked for aarch64-linux-android: this needs the Android NDK
#      (its clang and the bionic sysroot: libc, libm, libdl, liblog, libandroid stubs
#      and crt objects), which no Debian package provides. Without it the script stops
#      here, naming what to install;
#   4. the library added (lib/arm64-v8a/), aligned, signed with a debug key
#      (~/.android/debug.keystore, made with keytool when missing) and verified.
set -euo pipefail
cd "$(dirname "$0")/.."
out=target/android
mkdir -p "$out"

say() { echo "android-apk.sh: $*" >&2; }
apt_install() {
  local missing=()
  for pkg in "$@"; do dpkg -s "$pkg" >/dev/null 2>&1 || missing+=("$pkg"); done
  [ ${#missing[@]} -eq 0 ] && return 0
  say "installing ${missing[*]}"
  local sudo=""
  [ "$(id -u)" -ne 0 ] && sudo=sudo
  $sudo apt-get update -qq && $sudo apt-get install -y -qq "${missing[@]}"
}

# 1. Tools and the platform's resource table.
apt_install aapt zipalign apksigner
platform="${ANDROID_PLATFORM_RES:-}"
if [ -z "$platform" ]; then
  apt_install android-framework-res
  platform=/usr/share/android-framework-res/framework-res.apk
fi
[ -f "$platform" ] || { say "no platform resource table at $platform (set ANDROID_PLATFORM_RES to an android.jar)"; exit 1; }

# 2. Manifest and resources.
unsigned="$out/palpa-unaligned.apk"
aapt package -f -M android/AndroidManifest.xml -S android/res -I "$platform" -F "$unsigned"
say "manifest and resources packaged ($unsigned)"

# 3. The native library.
ndk="${ANDROID_NDK_HOME:-${ANDROID_NDK_ROOT:-}}"
api=26
clang="$ndk/toolchains/llvm/prebuilt/linux-x86_64/bin/aarch64-linux-android$api-clang"
if [ -z "$ndk" ] || [ ! -x "$clang" ]; then
  say "stopping before the native library: the Android NDK is missing."
  say "  libpalpa_app.so is linked by the NDK's clang against its bionic sysroot"
  say "  (libc, libm, libdl, liblog, libandroid stubs and crt objects); Debian has none of it."
  say "  Install NDK r26 or later (Android Studio's SDK Manager, 'sdkmanager \"ndk;26.3.11579264\"',"
  say "  or unzip android-ndk-r26d-linux.zip from developer.android.com/ndk/downloads) and run"
  say "    ANDROID_NDK_HOME=/path/to/android-ndk-r26d scripts/android-apk.sh"
  say "  expected: ${ndk:-\$ANDROID_NDK_HOME}/toolchains/llvm/prebuilt/linux-x86_64/bin/aarch64-linux-android$api-clang"
  exit 2
fi
rustup target list --installed | grep -qx aarch64-linux-android || rustup target add aarch64-linux-android
export CARGO_TARGET_AARCH64_LINUX_ANDROID_LINKER="$clang"
export CC_aarch64_linux_android="$clang"
export AR_aarch64_linux_android="$ndk/toolchains/llvm/prebuilt/linux-x86_64/bin/llvm-ar"
cargo build --locked --release -p palpa-app --lib --no-default-features --target aarch64-linux-android
lib=target/aarch64-linux-android/release/libpalpa_app.so
stage="$out/stage"
rm -rf "$stage" && mkdir -p "$stage/lib/arm64-v8a"
"$ndk/toolchains/llvm/prebuilt/linux-x86_64/bin/llvm-strip" --strip-unneeded -o "$stage/lib/arm64-v8a/libpalpa_app.so" "$lib"
say "libpalpa_app.so: $(stat -c %s "$stage/lib/arm64-v8a/libpalpa_app.so") bytes stripped"

# 4. Add, align, sign, verify.
(cd "$stage" && aapt add -f "../$(basename "$unsigned")" lib/arm64-v8a/libpalpa_app.so >/dev/null)
aligned="$out/palpa-aligned.apk"
zipalign -f -p 4 "$unsigned" "$aligned"
ks="$HOME/.android/debug.keystore"
if [ ! -f "$ks" ]; then
  mkdir -p "$(dirname "$ks")"
  keytool -genkeypair -keystore "$ks" -storepass android -keypass android -alias androiddebugkey \
    -keyalg RSA -keysize 2048 -validity 10000 -dname "CN=Android Debug,O=Android,C=US" >/dev/null
fi
apksigner sign --ks "$ks" --ks-pass pass:android --key-pass pass:android --out "$out/palpa.apk" "$aligned"
apksigner verify "$out/palpa.apk"
say "built $out/palpa.apk ($(stat -c %s "$out/palpa.apk") bytes): adb install -r $out/palpa.apk"
