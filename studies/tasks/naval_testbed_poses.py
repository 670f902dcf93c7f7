"""Writes naval_testbed_poses.csv: the 342 required poses of the naval testbed task.

Transcribed from ``naval_testbed/dimsynth/lufi_synth_traj.m`` of the public repository
SchapplM/robotics-paper_mdpi2025_dimsynth (Schappler et al., Robotics 14(3):29, 2025), with the
setting the synthesis used, ``refTraj = 'process+workspace'``: the surge/roll, sway/pitch and
heave/yaw motions and the corner points with one, two and three tilted axes, 357 rows, of which
``unique(..., 'rows', 'stable')`` keeps 342 in their first order. The file's world frame has
the cube centre at z = 1.0 m (the working height ``X1``); the poses here are given in the task
frame W at the cube centre (z up), so 1.0 m is subtracted from z. Angles are X-Y'-Z'' intrinsic
Euler angles (``r2eulxyz``; parasynth's ``xyz``), written in degrees; positions in millimetres.

Assumption (docs/tasks.md, the naval testbed): the robot hangs, and its tool frame E at rest
points down (E's z axis, like the platform's, points away from the base). The listed angles tilt
E from that rest orientation about its own axes: ``R_WE = Rx(180 deg) Rx(alpha) Ry(beta) Rz(gamma)``,
whose X-Y'-Z'' angles are ``(alpha + 180 deg, beta, gamma)``. So the file's alpha column is the
listed alpha plus 180 deg (wrapped to (-180, 180] deg); beta and gamma are as listed.

``naval_testbed_path.csv`` holds all 357 rows in their order, duplicates included: the
path of ``lufi_synth_traj.m`` runs through every row of ``XE`` (``traj_trapez2_multipoint(XE,
...)``; only the pose checks use the unique rows), so it returns to poses it has visited (the
working height ``X1`` at the end of each motion group, the top centre ``X0``). The studies give
it as the trajectory's ``waypoints``.

The variant ``naval_testbed_729_poses.csv`` is the full grid of the same cube: the 27 positions
each with all 27 orientations (:func:`grid_729_in_W`), in the same conventions.

Run ``python studies/tasks/naval_testbed_poses.py`` to write the files again.
"""

from pathlib import Path

import numpy as np

B_WS = 0.100  # half width of the cube (m)
H_WS = 0.200  # height of the cube (m)
PHI = np.deg2rad(15.0)  # tilt of every axis
REST_ALPHA_DEG = 180.0  # the hanging tool's rest orientation, Rx(180 deg) in W


def rows() -> np.ndarray:
    """The 357 rows of XE = [SR; SP; HY; IL] of lufi_synth_traj.m (x, y, z in m, Euler xyz in rad),
    in the file's world frame."""
    X0 = np.array([0, 0, 1.1, 0, 0, 0.0])
    X1 = X0 + [0, 0, -H_WS / 2, 0, 0, 0]
    # rotx(0) etc. in r2eulxyz give zero angles; rotx(+-phi) gives (+-phi, 0, 0) and so on
    SR = [X1]
    for z in (1, 0, -1):  # alpha = 0 only (xp = 0): Pos = [+-b, 0, z h/2]
        SR.append(X1 + [B_WS, 0, z * H_WS / 2, 0, 0, 0])
        SR.append(X1 + [-B_WS, 0, z * H_WS / 2, 0, 0, 0])
        SR.append(X1 + [0, 0, z * H_WS / 2, PHI, 0, 0])
        SR.append(X1 + [0, 0, z * H_WS / 2, -PHI, 0, 0])
    SR.append(X1)
    SP = [X0]
    for z in (1, 0, -1):
        SP.append(X1 + [0, B_WS, z * H_WS / 2, 0, 0, 0])
        SP.append(X1 + [0, -B_WS, z * H_WS / 2, 0, PHI, 0])
        SP.append(X1 + [0, 0, z * H_WS / 2, 0, 0, 0])
        SP.append(X1 + [0, 0, z * H_WS / 2, 0, PHI, 0])
    SP.append(X1)
    HY = [X1]
    for z in (1, 0, -1):
        HY.append(X1 + [0, 0, z * H_WS / 2, 0, 0, 0])
        HY.append(X1 + [0, 0, z * H_WS / 2, 0, 0, PHI])
        HY.append(X1 + [0, 0, z * H_WS / 2, 0, 0, -PHI])
        HY.append(X1 + [0, 0, z * H_WS / 2, 0, 0, 0])
    HY.append(X1)
    IL = []
    single = [(1, 0, 0), (-1, 0, 0), (0, 1, 0), (0, -1, 0), (0, 0, 1), (0, 0, -1)]
    double = [(1, 1, 0), (-1, 1, 0), (1, -1, 0), (-1, -1, 0), (1, 0, 1), (-1, 0, 1), (1, 0, -1), (-1, 0, -1),
              (0, 1, 1), (0, 1, -1), (0, -1, 1), (0, -1, -1)]
    triple = [(1, 1, 1), (-1, 1, 1), (1, -1, 1), (1, 1, -1), (-1, -1, 1), (-1, 1, -1), (1, -1, -1), (-1, -1, -1)]
    jP, lP = [1, 1, -1, -1], [1, -1, -1, 1]
    for i in (1, 0, -1):
        for j, l in zip(jP, lP):
            for a in single + double + triple:
                IL.append(X1 + [j * B_WS, l * B_WS, i * 0.1, a[0] * PHI, a[1] * PHI, a[2] * PHI])
        # after the loop MATLAB's m is 4: lPoints(4) = 1
        IL.append(X1 + [jP[0] * B_WS, lP[3] * B_WS, i * 0.1, PHI, PHI, PHI])
    return np.array(SR + SP + HY + IL)


def unique_stable(X: np.ndarray) -> np.ndarray:
    """MATLAB's unique(X, 'rows', 'stable') (rows compared after rounding away float noise)."""
    seen, out = set(), []
    for r in X:
        k = tuple(np.round(r, 12))
        if k not in seen:
            seen.add(k)
            out.append(r)
    return np.array(out)


def poses_in_W() -> np.ndarray:
    """The 342 poses, W at the cube centre: x, y, z (m), alpha, beta, gamma (rad)."""
    X = unique_stable(rows())
    X[:, 2] -= 1.0
    return X


def _serpentine(values_per_axis):
    """Every combination of the axes' values, the last axis fastest, each axis reversing its
    direction whenever a slower one steps (a boustrophedon: neighbours differ in one value)."""
    out = [()]
    for vals in values_per_axis:
        nxt = []
        for i, head in enumerate(out):
            for v in (vals if i % 2 == 0 else vals[::-1]):
                nxt.append(head + (v,))
        out = nxt
    return out


def grid_729_in_W() -> np.ndarray:
    """The full grid of the variant: the 27 positions of the cube (x, y, z in {-100, 0, 100} mm)
    each with the 27 orientations (alpha, beta, gamma in {-15, 0, 15} deg), 729 poses in W. Order:
    the positions from the top layer down in a serpentine, at each position the orientations in a
    serpentine, so that consecutive poses differ in one coordinate."""
    pos = _serpentine([(H_WS / 2, 0.0, -H_WS / 2),
                       (-B_WS, 0.0, B_WS), (-B_WS, 0.0, B_WS)])
    ori = _serpentine([(-PHI, 0.0, PHI)] * 3)
    rows_, k = [], 0
    for z, y, x in pos:
        o = ori if k % 2 == 0 else ori[::-1]
        k += 1
        rows_ += [[x, y, z, a, b, g] for a, b, g in o]
    return np.array(rows_)


def _write(path: Path, X: np.ndarray, title: str) -> Path:
    lines = [f"# {title} (studies/tasks/naval_testbed_poses.py)",
             "x [mm],y [mm],z [mm],alpha [deg],beta [deg],gamma [deg]"]
    for r in X:
        ang = np.rad2deg(r[3:]) + [REST_ALPHA_DEG, 0.0, 0.0]
        ang[0] = (ang[0] + 180.0) % 360.0 - 180.0
        if ang[0] == -180.0:
            ang[0] = 180.0
        vals = list(np.round(1000 * r[:3], 6)) + list(np.round(ang, 6))
        lines.append(",".join(f"{v:g}" for v in vals))
    path.write_text("\n".join(lines) + "\n")
    return path


def main(path: Path = Path(__file__).with_name("naval_testbed_poses.csv")) -> Path:
    return _write(path, poses_in_W(), "the naval testbed's 342 required tool poses in W")


def main_path(path: Path = Path(__file__).with_name("naval_testbed_path.csv")) -> Path:
    X = rows()
    X[:, 2] -= 1.0
    return _write(path, X, "the naval testbed's path: all 357 rows of XE in order, duplicates included")


def main_729(path: Path = Path(__file__).with_name("naval_testbed_729_poses.csv")) -> Path:
    return _write(path, grid_729_in_W(), "the naval testbed's full grid: 729 required tool poses in W")


if __name__ == "__main__":
    X = rows()
    assert len(X) == 357, len(X)
    assert len(unique_stable(X)) == 342, len(unique_stable(X))
    print(main())
    print(main_path())
    print(main_729())
