"""PGMORL's evolution (Xu et al. 2020): the prediction model of each policy's improvement, the
performance buffer and the prediction-guided task selection.

Facts from MORL-Baselines' ``multi_policy/pgmorl/pgmorl.py`` (the authors' code), written again:

* :func:`generate_weights` -- every weight vector on the grid of step ``delta`` summing to 1.
* :class:`PerformancePredictor` -- for a policy with evaluation ``F``: the stored (weight, before, after) samples
  whose ``before`` lies within ``threshold * |F|`` of ``F`` (the threshold and the kernel width doubled until at
  least 4 distinct samples are found), weighted by ``exp(-(|after - F| / |F|)^2 / (2 sigma^2))``; per objective
  ``j`` a robust (soft-L1, ``f_scale`` 20) least-squares fit of ``delta_j = A tanh(a (w_j - b) / 2) + c`` (written
  ``A (e^{a(x-b)} - 1) / (e^{a(x-b)} + 1) + c``) with bounds ``A in [0, clip(range, 1, 500)]``, ``a in [0.1, 20]``,
  ``b in [-5, 5]``, ``c in [-500, 500]``, from ``(1, 1, 1, 1)``. The fit depends on ``F`` only, so it is made once
  per policy and evaluated at every weight.
* :class:`PerformanceBuffer` -- 2 objectives: ``num_bins`` angular bins of the quarter plane;
  3 objectives: one bin per direction of ``generate_weights(1 / (num_bins - 1), 3)``
  (normalised), the bin of largest dot product. Evaluations are centred on ``origin`` and
  clipped at 0; each bin keeps its ``size`` entries of largest norm.
* :func:`select_tasks` -- for each of the ``P`` slots, among every (buffer policy,
  candidate weight of ``generate_weights(delta / 2)``, shuffled) pair not chosen yet, the one
  whose predicted evaluation maximises ``HV(front + [pred]) + sparsity_coef * sparsity(front +
  [pred])``; the prediction joins the front before the next slot is chosen.
"""

from __future__ import annotations

import numpy as np

from morl_trl.metrics import hypervolume, pareto_front, sparsity

__all__ = ["generate_weights", "PerformancePredictor", "PerformanceBuffer", "select_tasks"]


def generate_weights(delta: float, num_objectives: int) -> np.ndarray:
    """The weights on the grid ``{0, delta, 2 delta, ..., 1}^k`` that sum to 1, in product order.

    Example:
        >>> generate_weights(0.5, 2).tolist()
        [[0.0, 1.0], [0.5, 0.5], [1.0, 0.0]]
        >>> len(generate_weights(0.25, 3))
        15
    """
    n = int(round(1.0 / delta))
    if n < 1 or abs(n * delta - 1.0) > 1e-6:
        raise ValueError(f"delta must divide 1 (e.g. 0.2, 0.25), got {delta!r}")

    def compositions(total, k):
        if k == 1:
            yield (total,)
            return
        for i in range(total + 1):
            for rest in compositions(total - i, k - 1):
                yield (i, *rest)

    return np.array(list(compositions(n, num_objectives)), dtype=np.float32) / n


def _f(x, A, a, b, c):
    e = np.exp(a * (x - b))
    return A * (e - 1.0) / (e + 1.0) + c


class PerformancePredictor:
    """Predicts the evaluation of a policy after training it with a weight (see the module).

    Example:
        >>> pp = PerformancePredictor()
        >>> for w0, gain in [(0.0, 0.0), (0.25, 5.0), (0.5, 10.0), (0.75, 15.0), (1.0, 20.0)]:
        ...     pp.add(np.array([w0, 1 - w0]), np.array([100.0, 100.0]), np.array([100.0 + gain, 120.0 - gain]))
        >>> delta, nxt = pp.predict(np.array([[0.9, 0.1], [0.1, 0.9]]), np.array([100.0, 100.0]))
        >>> bool(delta[0, 0] > delta[1, 0]) and bool(delta[0, 1] < delta[1, 1])   # more weight, more improvement
        True
    """

    def __init__(self, neighborhood_threshold: float = 0.1, sigma: float = 0.03, f_scale: float = 20.0) -> None:
        self.neighborhood_threshold, self.sigma, self.f_scale = neighborhood_threshold, sigma, f_scale
        self.weights: list[np.ndarray] = []
        self.before: list[np.ndarray] = []
        self.after: list[np.ndarray] = []

    def add(self, weight, before, after) -> None:
        self.weights.append(np.asarray(weight, dtype=np.float64))
        self.before.append(np.asarray(before, dtype=np.float64))
        self.after.append(np.asarray(after, dtype=np.float64))

    def __len__(self) -> int:
        return len(self.weights)

    def _neighbours(self, evaluation: np.ndarray):
        distinct = {tuple(a) for a in self.after}
        if len(distinct) < 4:
            raise ValueError(f"the prediction model needs at least 4 distinct samples, it has {len(distinct)}")
        sigma, threshold = self.sigma / 2.0, self.neighborhood_threshold / 2.0
        scale = np.abs(evaluation)
        for _ in range(64):
            sigma, threshold = sigma * 2.0, threshold * 2.0
            chosen, seen = [], set()
            for w, b, a in zip(self.weights, self.before, self.after):
                if np.all(np.abs(b - evaluation) < threshold * scale) and tuple(a) not in seen:
                    chosen.append((w, a - b, a))
                    seen.add(tuple(a))
            if len(chosen) >= 4:
                return chosen, sigma
        # |F| has zeros (the neighbourhood cannot grow there): every distinct sample, as the limit of the growth
        chosen, seen = [], set()
        for w, b, a in zip(self.weights, self.before, self.after):
            if tuple(a) not in seen:
                chosen.append((w, a - b, a))
                seen.add(tuple(a))
        return chosen, sigma

    def fit(self, evaluation) -> np.ndarray:
        """The model parameters ``[k, 4]`` (``A, a, b, c`` per objective) for a policy evaluated at ``evaluation``."""
        from scipy.optimize import least_squares

        evaluation = np.asarray(evaluation, dtype=np.float64)
        chosen, sigma = self._neighbours(evaluation)
        W = np.array([c[0] for c in chosen])
        D = np.array([c[1] for c in chosen])
        A_ = np.array([c[2] for c in chosen])
        with np.errstate(divide="ignore", invalid="ignore"):
            dist = np.linalg.norm(np.abs(A_ - evaluation) / np.abs(evaluation), axis=-1)
        coef = np.nan_to_num(np.exp(-((dist / sigma) ** 2) / 2.0))
        params = []
        for j in range(evaluation.shape[0]):
            x, y = W[:, j], D[:, j]

            def residual(p, x=x, y=y):
                return (_f(x, *p) - y) * coef

            def jac(p, x=x):
                A, a, b, _ = p
                e = np.exp(a * (x - b))
                J = np.stack([(e - 1) / (e + 1), A * (x - b) * 2 * e / (e + 1) ** 2, A * (-a) * 2 * e / (e + 1) ** 2,
                              np.ones_like(x)], -1)
                return J * coef[:, None]

            upper_A = float(np.clip(y.max() - y.min(), 1.0, 500.0))
            res = least_squares(residual, np.ones(4), jac=jac, loss="soft_l1", f_scale=self.f_scale,
                                bounds=([0.0, 0.1, -5.0, -500.0], [upper_A, 20.0, 5.0, 500.0]))
            params.append(res.x)
        return np.array(params)

    def predict(self, weights, evaluation) -> tuple[np.ndarray, np.ndarray]:
        """``(delta [n, k], evaluation + delta)`` for ``weights [n, k]`` (one fit for all of them)."""
        weights = np.atleast_2d(np.asarray(weights, dtype=np.float64))
        params = self.fit(evaluation)
        delta = np.stack([_f(weights[:, j], *params[j]) for j in range(params.shape[0])], -1)
        return delta, np.asarray(evaluation, dtype=np.float64) + delta


class PerformanceBuffer:
    """The population: bins over the objective space, each keeping its ``size`` best (largest norm) policies.

    Example:
        >>> buf = PerformanceBuffer(num_bins=4, size=1, origin=np.zeros(2))
        >>> buf.add("a", np.array([1.0, 0.1])); buf.add("b", np.array([2.0, 0.2])); buf.add("c", np.array([0.1, 1.0]))
        >>> sorted(buf.individuals)           # "b" replaced "a" in their bin
        ['b', 'c']
    """

    def __init__(self, num_bins: int, size: int, origin) -> None:
        self.size = size
        self.origin = np.asarray(origin, dtype=np.float64)
        k = self.origin.shape[0]
        if k == 2:
            self.num_bins = num_bins
            self.dtheta = np.pi / 2.0 / num_bins
            self.directions = None
        elif k == 3:
            d = generate_weights(1.0 / (num_bins - 1), 3).astype(np.float64)
            self.directions = d / np.linalg.norm(d, axis=-1, keepdims=True)
            self.num_bins = len(d)
        else:
            raise ValueError(f"PGMORL's performance buffer supports 2 or 3 objectives, got {k}")
        self.bins: list[list] = [[] for _ in range(self.num_bins)]
        self.bins_evals: list[list] = [[] for _ in range(self.num_bins)]

    def _center(self, evaluation):
        return np.clip(np.asarray(evaluation, dtype=np.float64) - self.origin, 0.0, None)

    def add(self, candidate, evaluation) -> None:
        c = self._center(evaluation)
        norm = np.linalg.norm(c)
        if self.directions is None:
            theta = np.arccos(np.clip(c[1] / (norm + 1e-3), -1.0, 1.0))
            b = int(theta // self.dtheta)
            if b < 0 or b >= self.num_bins:
                return
        else:
            b = int(np.argmax(self.directions @ c))
        for i, e in enumerate(self.bins_evals[b]):
            if norm < np.linalg.norm(self._center(e)):
                self.bins[b].insert(i, candidate)
                self.bins_evals[b].insert(i, np.asarray(evaluation, dtype=np.float64))
                break
        else:
            self.bins[b].append(candidate)
            self.bins_evals[b].append(np.asarray(evaluation, dtype=np.float64))
        if len(self.bins[b]) > self.size:
            self.bins[b].pop(0)
            self.bins_evals[b].pop(0)

    @property
    def individuals(self) -> list:
        return [c for b in self.bins for c in b]

    @property
    def evaluations(self) -> list[np.ndarray]:
        return [e for b in self.bins_evals for e in b]

    def state_dict(self) -> dict:
        return {"bins": self.bins, "bins_evals": self.bins_evals}

    def load_state_dict(self, state: dict) -> None:
        self.bins, self.bins_evals = state["bins"], state["bins_evals"]


def select_tasks(buffer: PerformanceBuffer, front: list, predictor: PerformancePredictor, num_tasks: int, *,
                 delta_weight: float, ref_point, sparsity_coef: float, rng: np.random.Generator):
    """``num_tasks`` ``(buffer index, weight, predicted evaluation)`` triples (see the module)."""
    k = len(ref_point)
    weights = generate_weights(delta_weight / 2.0, k)
    rng.shuffle(weights)
    front = [np.asarray(f, dtype=np.float64) for f in front]
    evals = buffer.evaluations
    predictions = [predictor.predict(weights, e)[1] for e in evals]  # one fit per policy
    chosen: list = []
    taken: set = set()
    for _ in range(num_tasks):
        best = (-np.inf, None, None, None)
        for i, (e, pred) in enumerate(zip(evals, predictions)):
            for j, w in enumerate(weights):
                if (tuple(e), tuple(w)) in taken:
                    continue
                pts = np.array(front + [pred[j]])
                score = hypervolume(pts, ref_point) + sparsity_coef * sparsity(pts)
                if score > best[0]:
                    best = (score, i, w, pred[j])
        if best[1] is None:
            raise ValueError("no (policy, weight) pair is left to choose from")
        _, i, w, pred = best
        taken.add((tuple(evals[i]), tuple(w)))
        front.append(pred)
        chosen.append((i, w.copy(), pred))
    return chosen


def nondominated(points: list) -> list:
    """The Pareto archive's evaluations: the non-dominated, de-duplicated subset."""
    if not points:
        return []
    return [np.asarray(p) for p in pareto_front(np.array(points, dtype=np.float64))]
