"""A trained policy, ready to act: :func:`load_policy` (from a run directory) and
:func:`train_policy` (``morl_trl.train``: train, then hand back the policy with the results).

A run directory holds everything to rebuild its policy: ``config.json`` (the algorithm, the domain, the networks
and the history length) and verified checkpoints (the trained weights). :func:`load_policy` rebuilds the run's eval
policy from the config, loads the weights of the newest intact checkpoint (:func:`morl_trl.runs.find_checkpoint`:
damaged ones are skipped) and returns a :class:`TrainedPolicy`, a TorchRL policy module that also knows the env
composition it was trained with (:meth:`TrainedPolicy.make_env`).

Example:
    >>> import morl_trl
    >>> result = morl_trl.train("envelope", "MOLavaGridDR-v0", quick=True, frames=2_000)  # doctest: +SKIP
    >>> policy = morl_trl.load_policy(result.run_dir)                                    # doctest: +SKIP
    >>> env = policy.make_env(num_envs=4, seed=0, preference=[0.7, 0.3])                 # doctest: +SKIP
    >>> env.rollout(100, policy)["next", "reward"].shape                                # doctest: +SKIP
    torch.Size([4, 100, 2])
"""

from __future__ import annotations

import json
import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import torch
from tensordict import TensorDictBase
from tensordict.nn import TensorDictModuleBase
from torchrl.envs import TransformedEnv
from torchrl.envs.utils import ExplorationType, set_exploration_type

from morl_trl.envs import domain_of, make_env as _make_env
from morl_trl.envs.trust import check_trusted
from morl_trl.recipes.config import TrainConfig, resolve_config
from morl_trl.algorithms.registry import build_agent, build_training_env
from morl_trl.recipes.off_policy import run_training
from morl_trl.training.parts import load_agent_state, run_discount, run_domain
from morl_trl.runs.atomic import atomic_write
from morl_trl.runs.checkpoint import DamagedCheckpointError, checkpoint_frames, find_checkpoint, load_checkpoint, verify_checkpoint
from morl_trl.runs.plain import UnsafeFileError, load_plain, save_plain
from morl_trl.runs.run_dir import check_writable
from morl_trl.transforms import PreferenceConditioning, compose_policy_env

__all__ = ["TrainedPolicy", "TrainResult", "export_policy", "load_policy", "train_policy"]

#: the key that marks a policy export (and its version)
EXPORT_FORMAT = "morl_trl_policy_export"


class TrainedPolicy(TensorDictModuleBase):
    """A run's eval policy with its trained weights, and the env composition it acts in.

    Called on a TensorDict holding ``"observation"`` (what :meth:`make_env` gives: the domain's observation, with
    the run's state–action history) and ``"preference"`` (``[*B, k]`` on the simplex), it writes ``"action"``,
    under the run's evaluation exploration type (greedy / the mean action; sampled for discrete MOSAC), so
    ``env.rollout(n, policy)`` and TorchRL collectors use it as they are.

    Attributes:
        module: the eval policy module itself (``Agent.eval_policy``).
        config: the run's :class:`~morl_trl.recipes.TrainConfig`.
        env_id, history_len, objective_names: the training id, the history length of the
            policy's observation and the reward's objectives.
        preference_key: where the policy reads ``w`` (``"preference"``).
        exploration_type: the TorchRL exploration type the policy acts under.
        checkpoint, frames: the checkpoint the weights come from and its frame count.
    """

    preference_key = "preference"

    def __init__(self, module, *, config: TrainConfig, checkpoint: Path | None = None,
                 exploration_type: ExplorationType = ExplorationType.DETERMINISTIC, device="cpu", agent=None,
                 frames: int | None = None) -> None:
        super().__init__()
        object.__setattr__(self, "_agent", agent)  # (what save() writes; not a submodule)
        self.module = module
        self.in_keys = list(module.in_keys)
        self.out_keys = list(module.out_keys)
        self.config = config
        self.checkpoint = None if checkpoint is None else Path(checkpoint)
        self.frames = frames if checkpoint is None or checkpoint.is_file() else checkpoint_frames(checkpoint)
        self.exploration_type = exploration_type
        self.device = torch.device(device)

    @property
    def env_id(self) -> str:
        return self.config.env_id

    @property
    def history_len(self) -> int:
        return self.config.history_len

    @property
    def objective_names(self) -> tuple[str, ...]:
        return tuple(domain_of(self.env_id).objective_names)

    def forward(self, tensordict: TensorDictBase) -> TensorDictBase:
        with set_exploration_type(self.exploration_type):
            return self.module(tensordict)

    def make_env(self, env_id: str | None = None, num_envs: int = 1, seed: int | None = None, *,
                 preference=None, device=None, **context_overrides: Any) -> TransformedEnv:
        """The env this policy acts in: ``compose_policy_env(make_env(env_id, ...),
        history_len=self.history_len)`` plus :class:`~morl_trl.transforms.PreferenceConditioning`.

        Args:
            env_id: any id of the run's domain (default: the training id; e.g. one of its
                evaluation ids for a fixed context).
            num_envs, seed, context_overrides: as :func:`morl_trl.envs.make_env`.
            preference: ``w`` ``[k]`` for every sub-env, or ``[m, k]`` cycled over the
                sub-envs (``PreferenceConditioning(weights=...)``). ``None``: the preference is
                given at reset, ``env.reset(TensorDict(preference=w, batch_size=env.batch_size))``
                (mode ``"given"``; equal weights ``1/k`` until one is given).
            device: the env's device (default: the policy's).
        """
        env_id = self.env_id if env_id is None else env_id
        if domain_of(env_id).train_id != domain_of(self.env_id).train_id:
            raise ValueError(f"{env_id!r} is not of the domain this policy was trained on "
                             f"({domain_of(self.env_id).name}, {self.env_id!r})")
        env = compose_policy_env(_make_env(env_id, num_envs=num_envs, device=self.device if device is None else device,
                                           seed=seed, **context_overrides), history_len=self.history_len)
        k = len(self.objective_names)
        if preference is None:
            pref = PreferenceConditioning(k, mode="given", preference_key=self.preference_key)
        else:
            w = torch.as_tensor(preference, dtype=torch.float32)
            pref = PreferenceConditioning(k, weights=w.reshape(-1, w.shape[-1]) if w.ndim else w, mode="cycle",
                                          preference_key=self.preference_key)
        env.append_transform(pref)
        return env

    def save(self, path: str | Path) -> Path:
        """Write this policy as an export: what acting needs (the agent's networks and acting state, no optimizer
        state, no replay buffer), the run's config and the preference spec, as tensors and plain data (read with
        ``torch.load(weights_only=True)``), atomically. :func:`load_policy` reads it back.

        Example:
            >>> policy = load_policy("runs/my_run")  # doctest: +SKIP
            >>> policy.save("policy.pt")             # doctest: +SKIP
            >>> load_policy("policy.pt")             # doctest: +SKIP
        """
        if self._agent is None:
            raise ValueError("this TrainedPolicy was not built by load_policy / train_policy: nothing to save")
        state = self._agent.state_dict()
        state["optimizers"] = {}  # (refilled from a fresh agent on load: acting never reads them)
        k = len(self.objective_names)
        export = {
            EXPORT_FORMAT: 1, "config": json.dumps(self.config.to_dict(), sort_keys=True), "frames": self.frames,
            "agent": state, "exploration_type": self.exploration_type.name,
            "objective_names": list(self.objective_names),
            "preference": {"key": self.preference_key, "num_objectives": k, "space": "simplex (w >= 0, sum w = 1)"},
            "observation": {"env_id": self.env_id, "history_len": self.history_len},
        }
        path = Path(path)
        atomic_write(path, lambda fh: save_plain(export, fh))
        return path

    def __repr__(self) -> str:
        where = f", checkpoint={self.checkpoint.name!r}" if self.checkpoint is not None else ""
        return (f"TrainedPolicy(algo={self.config.algo!r}, env_id={self.env_id!r}, "
                f"history_len={self.history_len}{where})")


def _checkpoint_path(run_dir: Path, checkpoint) -> Path:
    """The verified checkpoint: ``None`` -> the newest intact one; a frame count or a name or path of a checkpoint
    directory -> that one (``ValueError`` if it is missing or damaged). Only ``state.pt`` is verified: acting never
    needs the replay buffer, and a running training may be pruning an older checkpoint's buffer meanwhile."""
    if checkpoint is None:
        ckpt, skipped = find_checkpoint(run_dir, only=("state.pt",))
        if ckpt is None:
            what = "; ".join(f"{p.name}: {why}" for p, why in skipped) or "there is none"
            raise ValueError(f"{str(run_dir)!r} has no intact checkpoint ({what})")
        for path, why in skipped:  # (said, as evaluate and resume say it)
            warnings.warn(f"skipped damaged checkpoint {path.name} of {str(run_dir)!r}: {why}; using {ckpt.name}",
                          stacklevel=3)
        return ckpt
    if isinstance(checkpoint, int) and not isinstance(checkpoint, bool):
        path = run_dir / "checkpoints" / f"frames_{checkpoint:012d}"
    else:
        path = Path(checkpoint)
        if not path.is_dir() and (run_dir / "checkpoints" / path).is_dir():
            path = run_dir / "checkpoints" / path
    if not path.is_dir():
        raise ValueError(f"checkpoint {str(path)!r} does not exist")
    problem = verify_checkpoint(path, only=("state.pt",))
    if problem is not None:
        raise ValueError(f"checkpoint {str(path)!r} is damaged: {problem}")
    return path


def _load_export(path: Path, device: torch.device, trust_code=False) -> TrainedPolicy:
    try:
        data = load_plain(path, map_location=device)
    except UnsafeFileError as err:
        raise type(err)(f"{err}; export the policy again (morl-trl export RUN --out FILE)") from None
    if not isinstance(data, dict) or data.get(EXPORT_FORMAT) != 1:
        raise ValueError(f"{str(path)!r} is not a policy export (written by TrainedPolicy.save / morl-trl export)")
    if not isinstance(data.get("config"), str):
        raise DamagedCheckpointError(f"{str(path)!r} holds no config (the policy export was changed): export the "
                                     f"policy again")
    import tempfile

    with tempfile.TemporaryDirectory() as tmp:  # (TrainConfig.load: the one reader of saved configs)
        (Path(tmp) / "config.json").write_text(data["config"])
        try:
            cfg = TrainConfig.load(Path(tmp) / "config.json").replace(device=str(device))
        except ValueError as err:
            raise ValueError(str(err).replace(repr(str(Path(tmp) / "config.json")), f"the config in {str(path)!r}")
                             ) from None
    check_trusted(cfg.domain_modules, trust_code, source=f"the policy export {str(path)!r}")
    agent = _build_agent(cfg, device)
    state = data.get("agent")
    if not isinstance(state, dict):
        raise DamagedCheckpointError(f"{str(path)!r} holds no agent state (the policy export was changed): export "
                                     f"the policy again")
    state["optimizers"] = {k: o.state_dict() for k, o in agent.optimizers.items()}
    load_agent_state(agent, {"agent": state}, path, cfg.algo)
    if data.get("exploration_type") not in ExplorationType.__members__:
        raise DamagedCheckpointError(f"{str(path)!r}: exploration_type is {data.get('exploration_type')!r}; valid: one "
                                     f"of {list(ExplorationType.__members__)} (the policy export was changed): export "
                                     f"the policy again")
    policy = TrainedPolicy(agent.eval_policy, config=cfg, checkpoint=path, device=device, agent=agent,
                           exploration_type=ExplorationType[data["exploration_type"]], frames=data["frames"])
    return policy.eval()


def _build_agent(cfg: TrainConfig, device: torch.device):
    spec = run_domain(cfg)
    # (only its specs are used: one sub-env, but PGMORL's layout fixes num_envs = pop x envs per member)
    env = build_training_env(cfg if cfg.algo == "pgmorl" else cfg.replace(num_envs=1), device)
    agent = build_agent(cfg, env, gamma=run_discount(cfg, spec), device=device)
    env.close()
    return agent


def export_policy(run_dir: str | Path, out: str | Path, checkpoint: str | Path | int | None = None, *,
                  trust_pickle: bool = False, trust_code: bool | list[str] = False) -> Path:
    """``morl-trl export RUN --out FILE``: :func:`load_policy` then :meth:`TrainedPolicy.save`.
    Reads the newest complete checkpoint (also while the run trains) and writes only ``out``."""
    out = Path(out)
    if out.is_dir():
        raise ValueError(f"--out {str(out)!r} is a folder; give a file name, e.g. {str(out / 'policy.pt')!r}")
    check_writable(out.parent, "the export's folder")
    return load_policy(run_dir, checkpoint, trust_pickle=trust_pickle, trust_code=trust_code).save(out)


def load_policy(run_dir: str | Path, checkpoint: str | Path | int | None = None, device: str | torch.device = "cpu", *,
                trust_pickle: bool = False, trust_code: bool | list[str] = False) -> TrainedPolicy:
    """The trained eval policy of a run directory, or of a policy export (see the module docstring).

    Args:
        run_dir: a run directory (``config.json`` and ``checkpoints/``), or a file written by
            :meth:`TrainedPolicy.save` / ``morl-trl export`` (no replay buffer needed either way).
        checkpoint: ``None`` for the newest intact checkpoint, else a frame count, a
            checkpoint directory name (``"frames_000000002048"``) or path; it is verified.
        device: where the policy's parameters go.
        trust_pickle: load a checkpoint of the old pickled format (it can run code stored in
            it: only for a run you trust; ``morl-trl convert-run`` converts it once instead).
        trust_code: import the domain modules the run's config names (``True``: all; a list:
            these); without it only modules already imported or registered by an installed
            package's entry point are (:mod:`morl_trl.envs.trust`).

    Raises:
        ValueError: ``run_dir`` is not a run directory, or has no intact checkpoint (naming it).
        UntrustedCodeError: the config names a domain module not trusted (nothing imported).
    """
    run_dir = Path(run_dir)
    if run_dir.is_file():
        if checkpoint is not None:
            raise ValueError(f"{str(run_dir)!r} is a policy export: it holds one policy, no checkpoints to choose")
        return _load_export(run_dir, torch.device(device), trust_code)
    if not (run_dir / "config.json").is_file():
        raise ValueError(f"{str(run_dir)!r} is not a run directory (no config.json) nor a policy export")
    cfg = TrainConfig.load(run_dir / "config.json")
    check_trusted(cfg.domain_modules, trust_code, source=repr(str(run_dir / "config.json")))
    ckpt = _checkpoint_path(run_dir, checkpoint)
    device = torch.device(device)
    cfg = cfg.replace(device=str(device))
    state = load_checkpoint(ckpt, map_location=device, trust_pickle=trust_pickle,  # (refused before any build)
                            keys={"agent": dict})
    agent = _build_agent(cfg, device)
    load_agent_state(agent, state, ckpt, cfg.algo)  # (the whole agent: some keep more than the loss, e.g. weights)
    policy = TrainedPolicy(agent.eval_policy, config=cfg, checkpoint=ckpt, exploration_type=agent.eval_exploration,
                           device=device, agent=agent)
    return policy.eval()


@dataclass
class TrainResult:
    """What :func:`train_policy` (``morl_trl.train``) returns.

    Attributes:
        run_dir: where the run was written.
        summary: the last evaluation summary (as :func:`morl_trl.recipes.train` returns it).
        report: the run's ``report.md`` (a property).
        policy: the trained policy, loaded from the run's final checkpoint (:func:`load_policy`).
        config: the config the run ran with.
        agent: the trained :class:`~morl_trl.recipes.Agent` in memory (loss, policies,
            optimizers); ``None`` when a resumed run had nothing left to do.
    """

    run_dir: Path
    summary: dict
    policy: TrainedPolicy
    config: TrainConfig
    agent: Any = None

    @property
    def report(self) -> Path | None:
        """The run's ``report.md`` (``None`` when the run wrote none, e.g. a resume with nothing to do)."""
        path = self.run_dir / "report.md"
        return path if path.is_file() else None


def train_policy(algo: str | TrainConfig | None = None, env_id: str | None = None, *, quick: bool = False,
                 config_file: str | Path | None = None, resume: str | Path | None = None, overwrite: bool = False,
                 trust_pickle: bool = False, trust_code: bool | list[str] = False, env=None, env_name: str | None = None,
                 **overrides: Any) -> TrainResult:
    """Train (the run ``morl-trl train`` makes) and return a :class:`TrainResult`.

    The run writes its directory and ``report.md`` as ``morl-trl train`` does and prints its
    progress and, at the end, the report's one-line summary (not its tables). Without
    ``run_dir`` each call gets a fresh directory (:func:`morl_trl.runs.default_run_dir`), so
    the same call runs twice; a given ``run_dir`` that holds a run needs ``overwrite=True``.

    ``train_policy("envelope", "MOLavaGridDR-v0", quick=True, frames=4_000, run_dir="runs/a")``
    resolves the config as :func:`~morl_trl.recipes.resolve_config` does (``algo`` may also be
    a ready :class:`TrainConfig`); ``resume=run_dir`` continues a run (the other arguments
    then are optional and may change only what a resume may change).

    ``env=`` may replace ``env_id``: an id (ours, or any Gymnasium / MO-Gymnasium id with a vector reward), a
    callable returning a TorchRL ``EnvBase`` with a vector reward, or an ``EnvBase`` (registered under
    ``env_name``, default its function or class name; see :func:`morl_trl.envs.register_env`). A callable or
    instance lives in this process only: to resume such a run, register it again under the same name first.
    """
    if env is not None:
        if env_id is not None:
            raise ValueError("give the env once: env_id or env=")
        if isinstance(env, str):
            env_id = env
        else:
            from morl_trl.envs import register_env

            name = env_name or getattr(env, "__name__", None) or type(env).__name__
            if name.startswith("<"):  # "<lambda>"
                raise ValueError("name the env: train(..., env=<callable>, env_name='my-env')")
            env_id = register_env(env, name=name, ref_point=overrides.get("ref_point"))
    if isinstance(algo, TrainConfig):
        if env_id is not None or quick or config_file is not None or overrides:
            raise ValueError("train_policy(cfg) takes a TrainConfig alone; put the overrides in it")
        cfg = algo
    elif algo is None:
        if resume is None:
            raise ValueError("train_policy() needs an algorithm and an env id (or resume=<run dir>)")
        cfg = None
    else:
        if env_id is None:
            raise ValueError("train_policy(algo, env_id, ...): env_id is missing")
        cfg = resolve_config(algo, env_id, quick=quick, config_file=config_file, **overrides)
    summary, agent, run_dir, cfg = run_training(cfg, resume=resume, overwrite=overwrite, trust_pickle=trust_pickle,
                                                trust_code=trust_code,
                                                echo_report=False)  # (one line: the report is in the run dir)
    policy = load_policy(run_dir, device=cfg.device, trust_code=trust_code)
    return TrainResult(run_dir=Path(run_dir), summary=summary, policy=policy, config=cfg, agent=agent)
