#!/usr/bin/env bash
# Debian packages prtbench uses at run time, installed when missing and possible (root + apt):
#  - libllvm19: Dr.Jit's LLVM backend, so Mitsuba's fast CPU variant llvm_ad_rgb can run
#    (without it the reference falls back to the much slower scalar_rgb);
#  - libegl1 libegl-mesa0 libgl1-mesa-dri: headless OpenGL through EGL on Mesa (llvmpipe);
#  - chromium: the headless browser `make test-browser` checks the comparison site in
#    (optional: without it those tests skip).
set -u
wanted="libllvm19 libegl1 libegl-mesa0 libgl1-mesa-dri chromium"
missing=""
for pkg in $wanted; do
  dpkg-query -W -f='${Status}' "$pkg" 2>/dev/null | grep -q "install ok installed" || missing="$missing $pkg"
done
[ -z "$missing" ] && exit 0
if [ "$(id -u)" = 0 ] && command -v apt-get >/dev/null; then
  echo "installing Debian packages:$missing"
  (apt-get install -y -q $missing >/dev/null 2>&1 || { apt-get update -q >/dev/null 2>&1 && apt-get install -y -q $missing >/dev/null 2>&1; }) \
    || echo "warning: could not install$missing; Mitsuba falls back to scalar_rgb / GL may be unavailable / browser tests skip" >&2
else
  echo "note: missing Debian packages:$missing (install them as root: apt-get install$missing)" >&2
fi
exit 0
