"""The greedy policy of a vector Q-network: TorchRL's ``QValueModule`` for a preference ``w``."""

from __future__ import annotations

import torch
from tensordict import TensorDictBase
from tensordict.nn import TensorDictModuleBase
from tensordict.utils import NestedKey

__all__ = ["MOQValueModule", "scalarized_argmax"]


def scalarized_argmax(action_value: torch.Tensor, preference: torch.Tensor) -> torch.Tensor:
    """``argmax_a w · Q(s, a, w)`` of ``action_value`` ``[*B, |A|, k]`` and ``preference`` ``[*B, k]``.

    Example:
        >>> q = torch.tensor([[[1.0, 0.0], [0.0, 1.0]]])   # [B=1, |A|=2, k=2]
        >>> scalarized_argmax(q, torch.tensor([[0.2, 0.8]]))
        tensor([1])
    """
    return (action_value * preference.unsqueeze(-2)).sum(-1).argmax(-1)


class MOQValueModule(TensorDictModuleBase):
    """Greedy actions of a vector Q-network under linear scalarization (a multi-objective ``QValueModule``).

    Reads the vector action values ``[*B, |A|, k]`` (what
    :func:`~morl_trl.objectives.make_vector_q_network` writes) and the preference ``[*B, k]``,
    and writes the greedy action ``argmax_a w · Q(s, a, w)`` (a categorical index ``[*B]``, or
    one-hot ``[*B, |A|]`` with ``action_space="one_hot"``) and the chosen vector value
    ``[*B, k]``. Chain it after the Q-network with
    :class:`~tensordict.nn.TensorDictSequential` to get the policy Envelope evaluates with; put
    TorchRL's ``EGreedyModule`` after it to explore.

    Args:
        action_space: ``"categorical"`` (default) or ``"one_hot"``.
        action_value_key, preference_key: the inputs.
        action_key, chosen_action_value_key: the outputs.

    Example:
        >>> from tensordict import TensorDict
        >>> from tensordict.nn import TensorDictSequential
        >>> from morl_trl.objectives import make_vector_q_network
        >>> qnet = make_vector_q_network(4, num_actions=3, num_objectives=2, num_cells=(8,))
        >>> policy = TensorDictSequential(qnet, MOQValueModule())
        >>> td = policy(TensorDict(observation=torch.zeros(5, 4), preference=torch.full((5, 2), 0.5), batch_size=[5]))
        >>> td["action"].shape, td["chosen_action_value"].shape
        (torch.Size([5]), torch.Size([5, 2]))
    """

    _SPACES = ("categorical", "one_hot")

    def __init__(
        self,
        action_space: str = "categorical",
        *,
        action_value_key: NestedKey = "action_value",
        preference_key: NestedKey = "preference",
        action_key: NestedKey = "action",
        chosen_action_value_key: NestedKey = "chosen_action_value",
    ) -> None:
        super().__init__()
        if action_space not in self._SPACES:
            raise ValueError(f"action_space={action_space!r}; valid values are {self._SPACES}")
        self.action_space = action_space
        self.in_keys = [action_value_key, preference_key]
        self.out_keys = [action_key, chosen_action_value_key]

    def forward(self, tensordict: TensorDictBase) -> TensorDictBase:
        q_key, w_key = self.in_keys
        action_key, chosen_key = self.out_keys
        q = tensordict.get(q_key)
        w = tensordict.get(w_key)
        if q.ndim < 2 or w.shape[-1] != q.shape[-1]:
            raise ValueError(
                f"MOQValueModule: action values {tuple(q.shape)} and preference {tuple(w.shape)} do not "
                "match; expected [*B, |A|, k] and [*B, k]"
            )
        index = scalarized_argmax(q, w.to(q.dtype))
        chosen = q.gather(-2, index[..., None, None].expand(*index.shape, 1, q.shape[-1])).squeeze(-2)
        action = index if self.action_space == "categorical" else torch.nn.functional.one_hot(index, q.shape[-2])
        tensordict.set(action_key, action)
        tensordict.set(chosen_key, chosen)
        return tensordict
