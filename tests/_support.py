"""Helpers shared by the test modules: model configurations, pose sampling near a
reference pose, finite differences and a few independent geometric utilities.

Nothing here calls the code under test to produce an expected value; the helpers only
build inputs (poses, seeds) and independent reference quantities (finite differences,
rotation matrices written out by hand).
"""

from __future__ import annotations

import numpy as np

import parasynth

#: (registry name, parameters) of every configuration the generic tests run on.
MODEL_CONFIGS = [
    ("4ups_1rps", {}),
    ("2rpu_2sps", {}),
    ("2rpu_2sps", {"coupled": False}),
    ("5pus_upu", {}),
    ("5pus_upu", {"platform": "pentagonal"}),
]
MODEL_IDS = ["4ups_1rps", "2rpu_2sps-coupled", "2rpu_2sps-uncoupled", "5pus_upu-rect", "5pus_upu-pent"]

_CACHE: dict = {}


def shipped_configs() -> list[tuple[str, dict]]:
    """(registry name, parameters) of every packaged mechanism at its defaults and with each
    variant choice other than the default."""
    out = []
    for name in parasynth.list_mechanisms():
        mech = parasynth.load_mechanism(name)
        out.append((name, {}))
        for var in getattr(mech.description, "variants", ()):
            for choice in var.choices:
                if choice != var.default:
                    out.append((name, {var.name: choice}))
    return out


def load(name: str, params: dict):
    """Load (and cache) a model; the models are immutable so sharing them is safe."""
    key = (name, tuple(sorted(params.items())))
    if key not in _CACHE:
        _CACHE[key] = parasynth.load_mechanism(name, **params)
    return _CACHE[key]


def spread(mech) -> np.ndarray:
    """Half-width of the sampling box around the centre pose: 0.15 rad for angles,
    20 mm for lengths."""
    return np.array([0.15 if c in mech.angular_coordinates else 0.02 for c in mech.task_coordinates])


def centre(mech) -> np.ndarray:
    """Centre of the sampling box. For the first (pentagonal) 5-PUS/UPU scheme the home pose
    is the paper's structural singularity, so the box is moved away from it."""
    X0 = np.array(mech.home, dtype=float)
    if mech.name == "5pus_upu" and mech.params.platform == "pentagonal":
        X0 = X0 + np.array([0.01, -0.01, 0.0, 0.2, -0.2])
    return X0


def sample_poses(mech, rng: np.random.Generator, n: int, scale: float = 1.0) -> np.ndarray:
    return centre(mech) + scale * spread(mech) * rng.uniform(-1.0, 1.0, size=(n, mech.n_task))


def fd_steps(mech) -> np.ndarray:
    """Central-difference steps: 1e-6 rad for angles and 1e-6 m for lengths."""
    return np.full(mech.n_task, 1e-6)


def central_difference(f, X: np.ndarray, h: np.ndarray) -> np.ndarray:
    """d f / d X by central differences for a batched f: (N, n) -> (N, ...)."""
    cols = []
    for j in range(X.shape[1]):
        e = np.zeros(X.shape[1])
        e[j] = h[j]
        cols.append((f(X + e) - f(X - e)) / (2 * h[j]))
    return np.stack(cols, axis=-1)


def vee(S: np.ndarray) -> np.ndarray:
    """Axial vector of the skew-symmetric part of 3x3 matrices (..., 3, 3)."""
    A = 0.5 * (S - np.swapaxes(S, -1, -2))
    return np.stack([A[..., 2, 1], A[..., 0, 2], A[..., 1, 0]], axis=-1)


def random_rotation(rng: np.random.Generator) -> np.ndarray:
    """Uniform random rotation (QR of a Gaussian matrix with the sign fixed)."""
    q, r = np.linalg.qr(rng.normal(size=(3, 3)))
    q = q * np.sign(np.diag(r))
    if np.linalg.det(q) < 0:
        q[:, 0] = -q[:, 0]
    return q


def closest_point_to_lines(points: np.ndarray, dirs: np.ndarray):
    """Least-squares point nearest to the lines (point_i, dir_i) and the largest distance
    from it to any of the lines."""
    d = dirs / np.linalg.norm(dirs, axis=1, keepdims=True)
    A = np.zeros((3, 3))
    b = np.zeros(3)
    for p, u in zip(points, d):
        M = np.eye(3) - np.outer(u, u)
        A += M
        b += M @ p
    c = np.linalg.lstsq(A, b, rcond=None)[0]
    dist = [np.linalg.norm((np.eye(3) - np.outer(u, u)) @ (c - p)) for p, u in zip(points, d)]
    return c, max(dist)


# -- Pareto fronts by their definitions (no sorting, no library) ------------------------------------
def brute_force_front(F, senses, feasible):
    """Non-dominated feasible set by the definition, pair by pair."""
    sign = np.array([1 if s == "minimize" else -1 for s in senses])
    G = F * sign
    out = []
    for i in range(len(G)):
        if not feasible[i]:
            continue
        dominated = False
        for j in range(len(G)):
            if j != i and feasible[j] and all(G[j] <= G[i]) and any(G[j] < G[i]):
                dominated = True
                break
        out.append(not dominated)
    mask = np.zeros(len(G), bool)
    mask[np.flatnonzero(feasible)] = out
    return mask


def brute_crowding(F):
    """Crowding distance by its definition, without sorting: for every design and objective the
    nearest values above and below among the others (distinct values assumed)."""
    n, m = F.shape
    d = np.zeros(n)
    for i in range(n):
        for j in range(m):
            above = [F[k, j] for k in range(n) if F[k, j] > F[i, j]]
            below = [F[k, j] for k in range(n) if F[k, j] < F[i, j]]
            if not above or not below:
                d[i] = np.inf
                continue
            d[i] += (min(above) - max(below)) / (F[:, j].max() - F[:, j].min())
    return d


def brute_spread(F, k):
    keep = list(range(len(F)))
    while len(keep) > k:
        d = brute_crowding(F[keep]) if len(keep) > 2 else np.full(len(keep), np.inf)
        smallest = min(d)
        worst = max(i for i in range(len(keep)) if d[i] == smallest)  # the later one on a tie
        keep.pop(worst)
    return keep


def engine_fallbacks(mech, caught) -> list:
    """The messages of the engine's fallback warnings among ``caught`` (``warnings.catch_warnings
    (record=True)``) other than the one a structure whose motion is solved on chain limbs'
    closure equations may give: its pose from NumPy (the compiled pose program does not hold the
    chains' nested solve), its feasibility and indices still compiled. The engine says each
    fallback once per process, so whether that one is among ``caught`` depends on what ran
    before (on an empty compile cache it comes later): allowed, not required."""
    from parasynth.model.chains import ChainLeg
    from parasynth.model.mechanism import EngineFallbackWarning

    d = getattr(mech, "description", None)
    solved_on_chains = (d is not None and d.task.solve is not None
                        and any(isinstance(leg, ChainLeg) for leg in getattr(mech, "legs", ())))
    return [str(x.message) for x in caught if issubclass(x.category, EngineFallbackWarning)
            and not (solved_on_chains and "pose_batch runs on NumPy" in str(x.message))]
