#!/bin/sh
# Runs Penumbra's GPU benchmark from the unpacked archive; arguments go to it (see
# --help). Needs a GPU's Vulkan driver (its ICD), nothing else:
# - no Vulkan loader on the machine (libvulkan.so.1): the packed one in lib/ is used;
# - NVIDIA without a display (a headless container): the GLX library that NVIDIA's
#   ICD file names cannot create an instance there ("Could not get 'vkCreateInstance'
#   via 'vk_icdGetInstanceProcAddr'"); its EGL library exports the same driver, so an
#   ICD file naming it is used instead, unless VK_ICD_FILENAMES or VK_DRIVER_FILES is set.
here=$(cd "$(dirname "$0")" && pwd)
if ! ldconfig -p 2>/dev/null | grep -q 'libvulkan\.so\.1 '; then
    echo "run.sh: no Vulkan loader on this machine: using the packed one" >&2
    LD_LIBRARY_PATH="$here/lib${LD_LIBRARY_PATH:+:$LD_LIBRARY_PATH}"
    export LD_LIBRARY_PATH
fi
if [ -z "${DISPLAY:-}${WAYLAND_DISPLAY:-}${VK_ICD_FILENAMES:-}${VK_DRIVER_FILES:-}" ]; then
    egl=$(ldconfig -p 2>/dev/null | grep -o '/[^ ]*libEGL_nvidia\.so\.0' | head -n 1)
    if [ -n "$egl" ]; then
        api=$(cat /usr/share/vulkan/icd.d/nvidia_icd.json /etc/vulkan/icd.d/nvidia_icd.json 2>/dev/null |
            grep -o '"api_version" *: *"[^"]*"' | head -n 1 | sed 's/.*"\([^"]*\)"$/\1/')
        icd=$(mktemp "${TMPDIR:-/tmp}/penumbra-nvidia-icd.XXXXXX")
        printf '{"file_format_version":"1.0.1","ICD":{"library_path":"%s","api_version":"%s"}}\n' "$egl" "${api:-1.3.0}" > "$icd"
        echo "run.sh: no display: NVIDIA's Vulkan driver through $egl" >&2
        VK_ICD_FILENAMES=$icd VK_DRIVER_FILES=$icd
        export VK_ICD_FILENAMES VK_DRIVER_FILES
    fi
fi
exec "$here/penumbra-bench" --scenes-dir "$here/scenes" "$@"
