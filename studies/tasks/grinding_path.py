"""Writes grinding_path.csv: the 2022 paper's grinding path as timed poses of the 4-UPS/1-RPS.

Wang et al. 2022 (the grinding robot), Section 4.5, eqs. (66)-(68), in the ``4ups_1rps``
model's task coordinates ``x, y`` (platform centre, mm) and the z-y-z angles ``alpha, beta,
gamma`` (deg):

* 0 <= t <= 5 s: ``x = 0.002 t^2`` m; 5 < t <= 10 s: ``x = 0.1 - 0.002 (t - 10)^2`` m;
  ``y = 0.45`` m (a straight line along x, 4 mm/s^2 up then down);
* 10 < t <= 50 s: ``x = 0.1 cos(pi (t - 10) / 20)`` m, ``y = 0.1 sin(pi (t - 10) / 20) + 0.45`` m
  (one circle of radius 0.1 m in 40 s);
* ``beta = -15 deg`` throughout (eq. (68)), ``alpha = gamma = 0``.

Sampled every ``DT`` = 0.25 s (201 rows), the time step of the ``max_force_trajectory`` and
``force_decoupling_ratio`` measures without a task. Run ``python studies/tasks/grinding_path.py``
to write the file again.
"""

from pathlib import Path

import numpy as np

DT = 0.25  # s
T_END = 50.0  # s
Y0 = 0.45  # m
BETA_DEG = -15.0


def rows() -> np.ndarray:
    """(t [s], x [m], y [m], alpha, beta, gamma [deg]) of every sample."""
    t = np.round(np.arange(0.0, T_END + 1e-9, DT), 12)
    x = np.where(t <= 5, 0.002 * t**2, 0.1 - 0.002 * (t - 10) ** 2)
    y = np.full_like(t, Y0)
    c = t > 10
    u = np.pi * (t[c] - 10) / 20
    x[c], y[c] = 0.1 * np.cos(u), 0.1 * np.sin(u) + Y0
    z = np.zeros_like(t)
    return np.column_stack([t, x, y, z, z + BETA_DEG, z])


def write(path: Path) -> None:
    r = rows()
    with open(path, "w", encoding="utf-8") as f:
        f.write("# The 2022 paper's grinding path, eqs. (66)-(68): written by grinding_path.py\n")
        f.write("t [s],x [mm],y [mm],alpha [deg],beta [deg],gamma [deg]\n")
        for t, x, y, a, b, g in r:
            f.write(f"{t:.2f},{x * 1000:.9f},{y * 1000:.9f},{a:g},{b:g},{g:g}\n")


if __name__ == "__main__":
    write(Path(__file__).with_suffix(".csv"))
