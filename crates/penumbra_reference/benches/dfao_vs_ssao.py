#!/usr/bin/env python3
"""DFAO and Bevy's SSAO side by side against ray-traced AO, on the same views.

usage: dfao_vs_ssao.py VIEWER SHARED_DIR OUT_DIR [--size 128x128] [--spp 256]

For each view below: the scene viewer (VIEWER, a built `examples/viewer` binary) renders
it headless twice — with `--ao-max-distance D` (DFAO, default settings otherwise) and
with `--ssao` (Bevy's `ScreenSpaceAmbientOcclusion`, its defaults) — and dumps the AO
it shades with; `SHARED_DIR/tools/ao_truth.py` ray-traces the AO of the same camera
(Embree, cosine-weighted, limited to D). Printed per view and method: mean |AO − truth|,
p95, bias (mean AO − truth) over the pixels all three cover, and the method's lavapipe
GPU time (`render/penumbra_dfao` or `render/ssao`, mean over the frames). Bevy's SSAO
has a fixed reach of 0.73 scene units (its GTAO effect radius), so each view also
reports the truth at that reach ("SSAO's own reach") for SSAO. Writes OUT_DIR/table.md.
"""
import json, subprocess, sys, re
from pathlib import Path
import numpy as np

# name, scene (under SHARED_DIR/scenes), eye, target, D (scene units)
VIEWS = [
    ("Cornell box (mm)", "CornellBox.glb", "-278,274,800", "-278,274,-280", 250.0),
    ("DepthOfFieldExample", "DepthOfFieldExample.glb", "0,2.5,5", "0,0.3,0", 1.5),
    ("PalmTree", "PalmTree/PalmTree.gltf", "6,4,10", "0,2,0", 10.0),
]
SSAO_REACH = 0.5 * 1.457  # bevy_pbr ssao.wgsl effect_radius


def arg(flag, default):
    return sys.argv[sys.argv.index(flag) + 1] if flag in sys.argv else default


def viewer(binary, scene, eye, target, size, out, extra):
    cmd = [binary, str(scene), "--headless", "--size", size, "--eye=" + eye,
           "--target=" + target, "--frames", "20", "--dump", str(out),
           "--out", str(out / "image.png")] + extra
    text = subprocess.run(cmd, check=True, capture_output=True, text=True).stdout
    times = dict(re.findall(r"diagnostic render/(\S+)/elapsed_gpu = ([0-9.]+)ms", text))
    return {k: float(v) for k, v in times.items()}


def truth(shared, scene, eye, target, size, spp, distance, out):
    subprocess.run([sys.executable, str(shared / "tools/ao_truth.py"), str(scene),
                    "--eye=" + eye, "--target=" + target, "--fov", "45", "--size", size,
                    "--max-distance", str(distance), "--spp", str(spp), "--out", str(out)],
                   check=True, capture_output=True, text=True)
    return np.load(out)


def figures(got, want):
    ok = np.isfinite(got) & np.isfinite(want)
    d = got[ok] - want[ok]
    return ok.sum(), np.abs(d).mean(), np.percentile(np.abs(d), 95), d.mean()


def main():
    binary, shared, out = sys.argv[1], Path(sys.argv[2]), Path(sys.argv[3])
    size, spp = arg("--size", "128x128"), int(arg("--spp", "256"))
    rows = ["| view | method | reach | pixels | mean \\|Δ\\| | p95 | bias | GPU ms |",
            "|---|---|---|---|---|---|---|---|"]
    for name, rel, eye, target, dist in VIEWS:
        scene = shared / "scenes" / rel
        base = out / rel.split("/")[-1].split(".")[0]
        (base / "dfao").mkdir(parents=True, exist_ok=True)
        (base / "ssao").mkdir(parents=True, exist_ok=True)
        t_dfao = viewer(binary, scene, eye, target, size, base / "dfao",
                        ["--ao-max-distance", str(dist)])
        t_ssao = viewer(binary, scene, eye, target, size, base / "ssao", ["--ssao"])
        dfao = np.load(base / "dfao/ao.npy")
        ssao = np.load(base / "ssao/ssao.npy")
        want = truth(shared, scene, eye, target, size, spp, dist, base / "truth.npy")
        want_ssao = truth(shared, scene, eye, target, size, spp, SSAO_REACH,
                          base / "truth_ssao_reach.npy")
        both = np.isfinite(dfao) & np.isfinite(ssao)
        for method, got, wanted, reach, ms in [
            ("DFAO (defaults)", dfao, want, dist, t_dfao.get("penumbra_dfao")),
            ("Bevy SSAO", ssao, want, dist, t_ssao.get("ssao")),
            ("Bevy SSAO", ssao, want_ssao, SSAO_REACH, t_ssao.get("ssao")),
        ]:
            n, mean, p95, bias = figures(np.where(both, got, np.nan), wanted)
            ms = "–" if ms is None else f"{ms:.2f}"
            rows.append(f"| {name} | {method} | {reach:g} | {n} | {mean:.3f} | {p95:.3f} "
                        f"| {bias:+.3f} | {ms} |")
        print(rows[-3], rows[-2], rows[-1], sep="\n", flush=True)
    (out / "table.md").write_text("\n".join(rows) + "\n")
    print("\n".join(rows))


if __name__ == "__main__":
    main()
