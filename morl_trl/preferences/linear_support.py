"""Linear support: the corner weights of a convex coverage set and the GPI-LS weight queue.

Pure preference geometry (numpy only). The corner weights of a set of value vectors
``V`` ``[n, k]`` are the vertices of the polyhedron ``{(w, u): w in simplex, V w <= u}``
(Roijers' thesis, Def. 19): the weights where the upper surface ``max_i v_i . w`` bends,
plus the simplex corners. The authors (MORL-Baselines) enumerate them with
``pycddlib==2.1.6``, whose API no longer exists; here every vertex is found by direct
enumeration: a vertex of a polyhedron in ``d = k + 1`` dimensions is a feasible point where
``d`` linearly independent constraints are active, so every choice of ``k`` active
constraints among the ``n`` value planes and the ``k`` faces ``w_j = 0`` (with ``sum w = 1``
always active) is solved as one batched ``(k+1) x (k+1)`` linear system, and the feasible,
distinct solutions are the corners. That is ``C(n + k, k)`` systems (n=30, k=4: 46k, a
few ms), exact, with no solver dependency.

Example:
    >>> import numpy as np
    >>> corner_weights(np.array([[1.0, 0.0], [0.0, 1.0]]))   # the two lines cross at w = (.5, .5)
    array([[0. , 1. ],
           [0.5, 0.5],
           [1. , 0. ]])
"""

from __future__ import annotations

import itertools
import random
from collections.abc import Callable, Sequence

import numpy as np

__all__ = ["corner_weights", "LinearSupport"]

_TOL = 1e-9


def corner_weights(values, *, decimals: int | None = 4) -> np.ndarray:
    """The corner weights ``[m, k]`` of the value vectors ``values`` ``[n, k]``, sorted lexicographically.

    ``decimals`` rounds the values first (the authors round to 4 decimals "to avoid numerical
    issues"; ``None``: no rounding). Raises ``ValueError`` for an empty or non-finite set.

    Example:
        >>> corner_weights(np.array([[2.0, 0.0, 0.0], [0.0, 2.0, 0.0], [0.0, 0.0, 2.0]])).round(4)
        array([[0.    , 0.    , 1.    ],
               [0.    , 0.5   , 0.5   ],
               [0.    , 1.    , 0.    ],
               [0.3333, 0.3333, 0.3333],
               [0.5   , 0.    , 0.5   ],
               [0.5   , 0.5   , 0.    ],
               [1.    , 0.    , 0.    ]])
    """
    V = np.asarray(values, dtype=np.float64)
    if V.ndim != 2 or V.shape[0] == 0 or V.shape[1] == 0:
        raise ValueError(f"values must be a non-empty [n, k] array of value vectors, got shape {V.shape}")
    if not np.isfinite(V).all():
        raise ValueError(f"values hold non-finite entries: {V[~np.isfinite(V).all(1)]}")
    if decimals is not None:
        V = np.round(V, decimals)
    n, k = V.shape
    # constraints a . (w, u) <= b: value planes v_i.w - u <= 0, faces -w_j <= 0; equality sum w = 1
    A = np.concatenate([np.concatenate([V, -np.ones((n, 1))], 1),
                        np.concatenate([-np.eye(k), np.zeros((k, 1))], 1)])
    b = np.zeros(n + k)
    eq = np.concatenate([np.ones(k), [0.0]])
    combos = np.array(list(itertools.combinations(range(n + k), k)), dtype=np.int64).reshape(-1, k)
    M = np.concatenate([A[combos], np.broadcast_to(eq, (len(combos), 1, k + 1))], 1)  # [C, k+1, k+1]
    rhs = np.concatenate([b[combos], np.ones((len(combos), 1))], 1)
    det = np.linalg.det(M)
    ok = np.abs(det) > 1e-12
    if not ok.any():
        return np.zeros((0, k))
    x = np.linalg.solve(M[ok], rhs[ok][..., None])[..., 0]  # [C', k+1]
    w, u = x[:, :k], x[:, k]
    scale = max(1.0, float(np.abs(V).max()))
    feasible = (w >= -_TOL).all(1) & (V @ w.T <= u + _TOL * scale).all(0)
    w = np.clip(w[feasible], 0.0, None)
    w = w / w.sum(1, keepdims=True)
    w = np.unique(np.round(w, 10), axis=0)
    return w


class LinearSupport:
    """The weight queue of OLS / GPI-LS (Alegre et al., AAMAS 2023), as the authors' ``LinearSupport``.

    Holds the partial convex coverage set (``ccs``: value vectors, with the weight each was
    found for in ``weight_support``) and the queue of corner weights. The first ``k`` weights
    are the extrema ``e_1 .. e_k``; then :meth:`next_weight` computes the corner weights of the
    CCS, gives each a priority and returns the one with the highest. GPI-LS's priority of a
    corner ``w_c`` is ``max_{v in G} v . w_c - max_{v in CCS} v . w_c``, where ``G`` holds the
    GPI policy's values at every corner weight (``gpi_values``); OLS's is the optimistic LP
    gap (:meth:`ols_priority`, scipy's HiGHS). With ``epsilon`` set, corners below it are dropped;
    when every priority is 0 the queue is shuffled (``rng``) so the same weight is not
    returned every iteration.

    Example:
        >>> ls = LinearSupport(2)
        >>> ls.next_weight()
        array([1., 0.])
        >>> ls.add_solution(np.array([1.0, 0.0]), np.array([1.0, 0.0]))
        >>> ls.next_weight()
        array([0., 1.])
        >>> ls.add_solution(np.array([0.0, 1.0]), np.array([0.0, 1.0]))
        >>> ls.next_weight(priority=lambda corners: np.where(corners[:, 0] == 0.5, 1.0, 0.0))
        array([0.5, 0.5])
    """

    def __init__(self, num_objectives: int, *, epsilon: float | None = None, seed: int | None = None) -> None:
        if isinstance(num_objectives, bool) or not isinstance(num_objectives, int) or num_objectives < 1:
            raise ValueError(f"num_objectives must be a positive int, got {num_objectives!r}")
        self.num_objectives = num_objectives
        self.epsilon = epsilon
        self.ccs: list[np.ndarray] = []
        self.weight_support: list[np.ndarray] = []
        self.visited_weights: list[np.ndarray] = []
        self.queue: list[tuple[float, np.ndarray]] = [(float("inf"), w) for w in np.eye(num_objectives)]
        self.rng = random.Random(seed)

    # ------------------------------------------------------------------ queue
    def corner_weights(self) -> np.ndarray:
        """The corner weights ``[m, k]`` of the current CCS."""
        return corner_weights(np.stack(self.ccs))

    def next_weight(self, priority: Callable[[np.ndarray], np.ndarray] | None = None,
                    gpi_values: np.ndarray | None = None) -> np.ndarray | None:
        """The next weight to train on (``None`` when the queue is empty).

        Once the CCS is not empty the queue is rebuilt from its corner weights, ranked by
        ``priority(corners) -> [m]`` if given, else by the GPI-LS priority of ``gpi_values``
        (``[m, k]``: the GPI policy's value at each corner, in the order of
        :meth:`corner_weights`), else by :meth:`ols_priority`.
        """
        if self.ccs:
            corners = self.corner_weights()
            if priority is not None:
                prio = np.asarray(priority(corners), dtype=np.float64)
            elif gpi_values is not None:
                prio = self.gpi_ls_priority(corners, gpi_values)
            else:
                prio = np.array([self.ols_priority(w) for w in corners])
            self.queue = []
            for p, wc in zip(prio, corners):
                if self.epsilon is None or p >= self.epsilon:
                    if priority is None and gpi_values is None and any(np.allclose(wc, v) for v in self.visited_weights):
                        continue  # OLS never tries a weight twice
                    self.queue.append((float(p), wc))
            self.queue.sort(key=lambda t: t[0], reverse=True)  # stable: ties keep the corners' order
            if self.queue and self.queue[0][0] == 0.0:
                self.rng.shuffle(self.queue)
        if not self.queue:
            return None
        return self.queue.pop(0)[1]

    def get_corner_weights(self, top_k: int | None = None) -> list[np.ndarray]:
        """The queued corner weights, best first (the authors add the top 4 to the GPI support)."""
        weights = [w.copy() for _, w in self.queue]
        return weights if top_k is None else weights[:top_k]

    def get_weight_support(self) -> list[np.ndarray]:
        return [w.copy() for w in self.weight_support]

    # ------------------------------------------------------------------ priorities
    def max_scalarized_value(self, w: np.ndarray) -> float | None:
        if not self.ccs:
            return None
        return float(np.max(np.stack(self.ccs) @ w))

    def gpi_ls_priority(self, corners: np.ndarray, gpi_values: np.ndarray) -> np.ndarray:
        """``[m]``: ``max_{v in gpi_values} v . w_c - max_{v in CCS} v . w_c`` for each corner ``w_c``."""
        corners, G = np.asarray(corners, np.float64), np.asarray(gpi_values, np.float64)
        best_gpi = (G @ corners.T).max(0)
        best_ccs = (np.stack(self.ccs) @ corners.T).max(0)
        return best_gpi - best_ccs

    def ols_priority(self, w: np.ndarray) -> float:
        """OLS: the optimistic value ``max_v w . v s.t. W v <= V*(W)`` (visited weights) minus the CCS's."""
        from scipy.optimize import linprog

        W = np.stack(self.visited_weights)
        bound = np.array([self.max_scalarized_value(x) for x in W])
        res = linprog(-np.asarray(w, np.float64), A_ub=W, b_ub=bound, bounds=[(None, None)] * self.num_objectives,
                      method="highs")
        optimistic = float("inf") if res.status == 3 else -res.fun
        return optimistic - self.max_scalarized_value(w)

    # ------------------------------------------------------------------ solutions
    def is_dominated(self, value: np.ndarray) -> bool:
        """No visited weight prefers ``value`` (at least as much) over the CCS."""
        if not self.ccs:
            return False
        return all(float(value @ w) < self.max_scalarized_value(w) for w in self.visited_weights)

    def add_solution(self, value, w) -> None:
        """Add the value ``value`` found for weight ``w``; drop CCS values optimal for no visited weight."""
        value, w = np.asarray(value, np.float64), np.asarray(w, np.float64)
        self.visited_weights.append(w)
        if self.is_dominated(value):
            return
        for i in reversed(range(len(self.ccs))):
            keeps = [x for x in self.visited_weights
                     if float(self.ccs[i] @ x) == self.max_scalarized_value(x) and float(value @ x) < float(self.ccs[i] @ x)]
            if not keeps:
                self.ccs.pop(i)
                self.weight_support.pop(i)
        self.ccs.append(value)
        self.weight_support.append(w)

    # ------------------------------------------------------------------ state
    def state_dict(self) -> dict:
        return {"ccs": [v.tolist() for v in self.ccs], "weight_support": [w.tolist() for w in self.weight_support],
                "visited": [w.tolist() for w in self.visited_weights],
                "queue": [(p, w.tolist()) for p, w in self.queue], "rng": self.rng.getstate()}

    def load_state_dict(self, state: dict) -> None:
        self.ccs = [np.asarray(v) for v in state["ccs"]]
        self.weight_support = [np.asarray(w) for w in state["weight_support"]]
        self.visited_weights = [np.asarray(w) for w in state["visited"]]
        self.queue = [(p, np.asarray(w)) for p, w in state["queue"]]
        self.rng.setstate(state["rng"])


def unique_weights(weights: Sequence[np.ndarray], tol: float = 1e-6) -> np.ndarray:
    """``weights`` without near-duplicates (first occurrence kept), as ``[m, k]``."""
    out: list[np.ndarray] = []
    for w in weights:
        if not any(np.allclose(w, x, atol=tol) for x in out):
            out.append(np.asarray(w, np.float64))
    return np.stack(out)
