#!/usr/bin/env python3
"""libigl's signed distance (fast winding number sign) on a Penumbra grid, timed.

Called by `benches/bake.rs` when `python3 -c "import igl"` works (`pip install numpy
libigl`). Usage: libigl_sdf.py MESH.obj OX OY OZ VOXEL NX NY NZ OUT.npy
Writes float32 distances shaped (nz, ny, nx) like `penumbra-bake --npy` and prints
`libigl_seconds <median of 5 runs of igl.signed_distance after a warm-up run>`.
"""
import sys
import time

import igl
import numpy as np


def load_obj(path):
    v, f = [], []
    with open(path) as file:
        for line in file:
            w = line.split()
            if not w:
                continue
            if w[0] == "v":
                v.append([float(x) for x in w[1:4]])
            elif w[0] == "f":
                idx = [int(x.split("/")[0]) for x in w[1:]]
                idx = [i - 1 if i > 0 else len(v) + i for i in idx]
                for k in range(1, len(idx) - 1):
                    f.append([idx[0], idx[k], idx[k + 1]])
    return np.array(v, dtype=np.float64), np.array(f, dtype=np.int64)


def main():
    mesh, ox, oy, oz, h, nx, ny, nz, out = sys.argv[1:10]
    origin = np.array([float(ox), float(oy), float(oz)])
    h = float(h)
    nx, ny, nz = int(nx), int(ny), int(nz)
    v, f = load_obj(mesh)
    k, j, i = np.meshgrid(np.arange(nz), np.arange(ny), np.arange(nx), indexing="ij")
    p = origin + h * np.stack([i, j, k], axis=-1).reshape(-1, 3).astype(np.float64)
    times = []
    # One untimed warm-up run, then 5 timed (as the Rust side does).
    igl.signed_distance(p, v, f, sign_type=igl.SIGNED_DISTANCE_TYPE_FAST_WINDING_NUMBER)
    for _ in range(5):
        t = time.perf_counter()
        s, _, _, _ = igl.signed_distance(
            p, v, f, sign_type=igl.SIGNED_DISTANCE_TYPE_FAST_WINDING_NUMBER
        )
        times.append(time.perf_counter() - t)
    median = sorted(times)[len(times) // 2]
    np.save(out, s.reshape(nz, ny, nx).astype(np.float32))
    print(f"libigl_seconds {median:.6f}")


if __name__ == "__main__":
    main()
