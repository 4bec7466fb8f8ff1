#!/usr/bin/env python3
"""How FCL's continuous solvers answer on meshes, against a dense sampling of the same motion.

  python bench/fcl/solver_check.py [--cases 60] [--seed 7]

Two sphere meshes (marching cubes of a 0.125 m sphere on a 64³ grid, as compare.py makes
them), the second 0.26-0.35 m from the first in a random direction, each translated by a
random vector over the period. The reference is FCL's naive solver at 2001 instants (a
discrete check every 1/2000 of the period) on the world-coordinate meshes under the pair's
relative translation. For every case with a contact inside the period, each way of asking
conservative advancement (CCDC_CONSERVATIVE_ADVANCEMENT, FCL's default) is counted as
missed, off by more than 1 % of the period, or right:

  posed      meshes around the origin, placed by their start transforms, one body moving
  both       meshes in world coordinates, identity start transforms, both bodies moving
  first      the same, the first body moved by the relative translation, the second still
  second     the same, the second body moved by minus the relative translation
  polynomial CCDC_POLYNOMIAL_SOLVER, world coordinates, the first body moving (fresh models per
             call: the solver moves a model's vertices in place)

compare.py uses `first`, the one that answers best.
"""

import argparse

import numpy as np


def sphere_mesh(r=0.125, n=64, edge=1.0):
    from skimage.measure import marching_cubes
    h = edge / n
    c = (np.arange(n) + 0.5) * h - edge / 2
    z, y, x = np.meshgrid(c, c, c, indexing="ij")
    occ = (x * x + y * y + z * z < r * r).astype(np.float32)
    v, f, _, _ = marching_cubes(np.pad(occ, 1), 0.5)
    v = (v[:, ::-1] - 0.5) * h - edge / 2
    return v, np.ascontiguousarray(f[:, ::-1])


def main():
    import fcl
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--cases", type=int, default=60)
    ap.add_argument("--seed", type=int, default=7)
    a = ap.parse_args()
    S = fcl.CCDSolverType
    v, f = sphere_mesh()

    def model(verts):
        b = fcl.BVHModel()
        b.beginModel(len(verts), len(f))
        b.addSubModel(verts, f)
        b.endModel()
        return b

    def ccd(solver, va, a0, a1, vb, b0, b1, iters=10):
        oa = fcl.CollisionObject(model(va), fcl.Transform(np.asarray(a0, float)))
        ob = fcl.CollisionObject(model(vb), fcl.Transform(np.asarray(b0, float)))
        req = fcl.ContinuousCollisionRequest(ccd_solver_type=solver, num_max_iterations=iters,
                                             toc_err=1e-6 if solver == S.CCDC_NAIVE else 1e-4)
        res = fcl.ContinuousCollisionResult()
        fcl.continuousCollide(oa, fcl.Transform(np.asarray(a1, float)), ob,
                              fcl.Transform(np.asarray(b1, float)), req, res)
        return res.is_collide, res.time_of_contact

    rng = np.random.default_rng(a.seed)
    z = np.zeros(3)
    ways = ("posed", "both", "first", "second", "polynomial")
    count = {w: [0, 0, 0] for w in ways}  # missed, off by > 1 %, right
    n = 0
    for _ in range(a.cases):
        pa = rng.uniform(-0.1, 0.1, 3)
        d = rng.normal(size=3)
        pb = pa + d / np.linalg.norm(d) * rng.uniform(0.26, 0.35)
        ma = rng.normal(scale=0.15, size=3) + (pb - pa) * 0.5
        mb = rng.normal(scale=0.15, size=3)
        va, vb = v + pa, v + pb
        ref = ccd(S.CCDC_NAIVE, va, z, ma - mb, vb, z, z, iters=2001)
        if not ref[0] or ref[1] == 0:
            continue  # no contact, or touching at the start
        n += 1
        got = {
            "posed": ccd(S.CCDC_CONSERVATIVE_ADVANCEMENT, v, pa, pa + ma - mb, v, pb, pb),
            "both": ccd(S.CCDC_CONSERVATIVE_ADVANCEMENT, va, z, ma, vb, z, mb),
            "first": ccd(S.CCDC_CONSERVATIVE_ADVANCEMENT, va, z, ma - mb, vb, z, z),
            "second": ccd(S.CCDC_CONSERVATIVE_ADVANCEMENT, va, z, z, vb, z, mb - ma),
            "polynomial": ccd(S.CCDC_POLYNOMIAL_SOLVER, va, z, ma - mb, vb, z, z),
        }
        for w, (hit, toc) in got.items():
            if not hit:
                count[w][0] += 1
            elif abs(toc - ref[1]) > 0.01:
                count[w][1] += 1
            else:
                count[w][2] += 1
    print(f"{n} cases with a contact inside the period ({len(f)} triangles per sphere)")
    print("| way | missed | off by > 1 % of the period | right |")
    print("|---|---|---|---|")
    for w in ways:
        print(f"| {w} | {count[w][0]} | {count[w][1]} | {count[w][2]} |")


if __name__ == "__main__":
    main()
