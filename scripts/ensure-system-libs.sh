#!/usr/bin/env bash
# Installs the system libraries refspatial-gen needs (headless EGL rendering for MuJoCo, libusb for open3d)
# when they are missing: with apt-get when running as root, otherwise stops with the exact command.
# Extra Debian package names as arguments (`make setup-blender` passes the X11/GL libraries bpy links).
set -euo pipefail
PKGS=(libegl1 libegl-mesa0 libgl1-mesa-dri libopengl0 libusb-1.0-0 "$@")
missing=()
for p in "${PKGS[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
[ ${#missing[@]} -eq 0 ] && exit 0
if ! command -v apt-get >/dev/null 2>&1; then
  echo "refspatial-gen needs these system libraries (Debian names): ${missing[*]}; install them with your package manager." >&2
  exit 1
fi
if [ "$(id -u)" -eq 0 ]; then
  echo "installing system libraries: ${missing[*]}"
  export DEBIAN_FRONTEND=noninteractive
  apt-get update -qq && apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
else
  echo "missing system libraries; run:  sudo apt-get install -y ${missing[*]}" >&2
  exit 1
fi
