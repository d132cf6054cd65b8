#!/usr/bin/env bash
# System packages Thicket needs on Debian: the software Vulkan driver (GPU tests run on
# llvmpipe/lavapipe), X11/Wayland client libraries for the editor window, Xvfb for screenshots,
# Goxel (the .vox round trip of models made with the voxel tools runs it under Xvfb), Blender
# with numpy (tests/tests/blender.rs imports the glTF exports headless, as artists would).
set -euo pipefail
pkgs=(mesa-vulkan-drivers libvulkan1 vulkan-tools libx11-6 libxcursor1 libxrandr2 libxi6
      libxkbcommon0 libxkbcommon-x11-0 libwayland-client0 libwayland-cursor0 libwayland-egl1
      libegl1 libgl1 xvfb xauth fonts-dejavu-core goxel blender python3-numpy)
missing=()
for p in "${pkgs[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -gt 0 ]; then
  SUDO=""
  [ "$(id -u)" -ne 0 ] && SUDO="sudo"
  export DEBIAN_FRONTEND=noninteractive
  $SUDO apt-get update -qq
  $SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}"
fi

# The Khronos glTF-Validator (npm `gltf-validator`, version pinned by the lock file) that the
# export tests run over every exported file. Needs node; once installed it runs offline.
if ! command -v node >/dev/null 2>&1 || ! command -v npm >/dev/null 2>&1; then
  SUDO=""
  [ "$(id -u)" -ne 0 ] && SUDO="sudo"
  export DEBIAN_FRONTEND=noninteractive
  $SUDO apt-get update -qq
  $SUDO apt-get install -y -qq --no-install-recommends nodejs npm
fi
# three.js (npm `three`, pinned likewise) for the test that loads exported files with its
# GLTFLoader in node. Each tool is installed with `npm ci` only when its pinned version is not.
tools_dir="$(cd "$(dirname "$0")/.." && pwd)/tools"
for tool in gltf-validator:gltf-validator threejs-check:three; do
  dir="$tools_dir/${tool%%:*}"
  package="${tool##*:}"
  wanted="$(node -e 'console.log(require(process.argv[1]).packages["node_modules/" + process.argv[2]].version)' "$dir/package-lock.json" "$package")"
  have="$(node -e 'try{console.log(require(process.argv[1]).version)}catch(e){console.log("none")}' "$dir/node_modules/$package/package.json")"
  if [ "$have" != "$wanted" ]; then
    (cd "$dir" && npm ci --no-audit --no-fund --loglevel=error)
  fi
done
