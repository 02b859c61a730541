#!/usr/bin/env bash
# System packages the tests need beyond Python packages: EGL + Mesa's software GL, so that
# pyvista/VTK render offscreen without a display, Debian's chromium + chromium-driver for the
# browser-viewer tests (tests/web) and Node.js for the JavaScript receiver's (tests/js).
# Installs them only when missing, and only when it can (root with apt-get); otherwise says
# what is missing and goes on (the screenshot and browser tests then skip with that reason).
set -u
need=()
ldconfig -p 2>/dev/null | grep -q 'libEGL.so.1' || need+=(libegl1)
ldconfig -p 2>/dev/null | grep -q 'libEGL_mesa.so.0' || need+=(libegl-mesa0)
[ -e /usr/lib/x86_64-linux-gnu/dri/swrast_dri.so ] || [ -e /usr/lib/aarch64-linux-gnu/dri/swrast_dri.so ] \
    || need+=(libgl1-mesa-dri)
ldconfig -p 2>/dev/null | grep -q 'libGL.so.1' || need+=(libgl1)
[ -x /usr/bin/chromium ] || need+=(chromium)
[ -x /usr/bin/chromedriver ] || need+=(chromium-driver)
command -v node >/dev/null 2>&1 || need+=(nodejs)  # the JavaScript receiver's tests (tests/js)
[ ${#need[@]} -eq 0 ] && exit 0
if [ "$(id -u)" = 0 ] && command -v apt-get >/dev/null 2>&1; then
    echo "installing offscreen GL, headless chromium, node: ${need[*]}"
    DEBIAN_FRONTEND=noninteractive apt-get update -qq >/dev/null \
        && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends "${need[@]}" >/dev/null \
        || echo "warning: could not install ${need[*]}; offscreen screenshot and browser tests will skip" >&2
else
    echo "note: missing ${need[*]} (install them for offscreen screenshots and browser tests)" >&2
fi
exit 0
