"""``init_grow: true``: an ``--init`` actor grown into an env with more observation entries or action components.

An actor is tied to its env's observation layout and action components. When a run's env adds some
(e.g. ``observation.scan.enabled``: the ``scan`` action component and the ``scanning`` /
``scan_result`` observation entries), :func:`grow_actor` copies the init actor into this run's
network, matching **by name**: every observation entry of the init env (its layout rebuilt from the
init run's sidecar: scenario, preset and ``env_overrides``) must be in this run's layout with the
same number of columns, wherever it sits, and every action component of the init env must be one
of this run's. Then:

- input scale: the init's centre / half-width (box or rollout-fitted) for the matching columns;
  a new entry keeps this env's box scale;
- first layer: the init's weights for the matching columns, zero for a new entry's columns (so a
  new entry does not change any output until the network learns to use it); the other hidden
  layers are copied;
- output layer (:func:`output_rows`: ``loc`` rows then pre-softplus ``scale`` rows, split by
  ``NormalParamExtractor``, then with the ``bernoulli`` scan head the scan logit): an init
  component's rows are copied to its new position; a new component's rows get zero weights, ``loc``
  bias ``loc`` and a ``scale`` bias such that the TanhNormal's scale is ``std``, or for a
  ``bernoulli`` scan the logit bias of the same scan probability ``Phi(loc / std)``
  (:func:`~parcover_env.harness.marl_scan_head.grown_scan_logit`). A component whose head differs
  (a ``continuous`` scan grown into a ``bernoulli`` one, or back) starts as a new one.

So on any observation the init components' loc and scale are exactly the init actor's, and a new
component's deterministic action is ``tanh(loc)`` (``MarlConfig.init_grow_loc``, default -1.5:
-0.905). The env reads ``scan`` as "start a scan when ``scan > 0``" (``ScanConfig``), so a grown
``scan`` starts at "no scan"; sampled actions scan with probability ``P(N(0,1) > -loc / std)``
per step (0.13 % at the defaults, about one scan per 740 steps per robot), which is how PPO meets
the new action at all. Hidden widths that differ, or an init entry / component this run lacks, is
one ParcoverError naming it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from parcover_env.errors import ParcoverError

__all__ = ["ACTION_COMPONENTS", "IoLayout", "Growth", "env_io", "output_rows", "grow_actor", "scale_bias"]

ACTION_COMPONENTS = ("v", "omega", "scan")
"""The action components in action order (``scan`` only with ``observation.scan.enabled``)."""


@dataclass(frozen=True)
class IoLayout:
    """What an actor's inputs and outputs mean: observation entries (name -> columns, in column
    order) and action component names (in action order)."""

    observation: dict[str, slice]
    actions: tuple[str, ...]
    scan_head: str = "continuous"
    """How the actor outputs ``scan`` (:data:`~parcover_env.policies.torchrl_policy.SCAN_HEADS`)."""


@dataclass(frozen=True)
class Growth:
    """How to grow an init actor (``init_grow: true``): the init env's and this env's
    :class:`IoLayout`, and a new action component's ``loc`` bias and TanhNormal ``std``."""

    init_io: IoLayout
    io: IoLayout
    loc: float
    std: float

    @property
    def changes(self) -> bool:
        """Whether the two layouts differ (else the init loads as it is)."""
        return self.init_io != self.io


def env_io(env, scan_head: str = "continuous") -> IoLayout:
    """The :class:`IoLayout` of a ParallelEnv or a :class:`~parcover_env.harness.map_pool.MapPoolEnv`
    (whose maps share the layout of its first map's env) for an actor of ``scan_head`` (``continuous``
    when the env has no ``scan``)."""
    layout = env.layout if hasattr(env, "layout") else env.env.layout
    width = env.action_space(env.possible_agents[0]).shape[0]
    actions = ACTION_COMPONENTS[:width]
    return IoLayout(dict(layout.slices), actions, scan_head if "scan" in actions else "continuous")


def output_rows(io: IoLayout) -> dict[str, tuple[int, ...]]:
    """The actor's output rows of each action component of ``io``: ``(loc, pre-scale)`` of a TanhNormal
    component, ``(logit,)`` of a ``bernoulli`` scan (the last output, after the drive's rows)."""
    if io.scan_head == "bernoulli":
        drive = [a for a in io.actions if a != "scan"]
        return {**{a: (i, len(drive) + i) for i, a in enumerate(drive)}, "scan": (2 * len(drive),)}
    return {a: (i, len(io.actions) + i) for i, a in enumerate(io.actions)}


def scale_bias(std: float) -> float:
    """The pre-softplus value that the actor's ``NormalParamExtractor`` (TorchRL's default biased
    softplus, ``softplus(x + bias) + min_val``) maps to the scale ``std``."""
    from tensordict.nn import NormalParamExtractor

    mapping = NormalParamExtractor().scale_mapping
    y = std - mapping.min_val
    if y <= 0:
        raise ParcoverError(f"init_grow_std {std} is not above the scale's floor {mapping.min_val}")
    return math.log(math.expm1(y)) - float(mapping.bias)


def _linear(net):
    import torch

    return [m for m in net if isinstance(m, torch.nn.Linear)]


def grow_actor(where: str, init_net, net, growth: Growth) -> dict:
    """Copy ``init_net`` (an :func:`~parcover_env.policies.torchrl_policy.actor_net` of
    ``growth.init_io``) into ``net`` (one of ``growth.io``) as the module docstring says. Returns
    ``{observation: [new entries], actions: [new components]}``. ``where`` names the init in errors."""
    import torch

    from parcover_env.harness.marl_scan_head import grown_scan_logit
    from parcover_env.policies.torchrl_policy import head_outputs

    init_io, io, loc, scale_pre = growth.init_io, growth.io, growth.loc, scale_bias(growth.std)
    old_lin, new_lin = _linear(init_net), _linear(net)
    old_hidden, new_hidden = [m.out_features for m in old_lin[:-1]], [m.out_features for m in new_lin[:-1]]
    if old_hidden != new_hidden:
        raise ParcoverError(f"--init {where}: its actor's hidden widths {old_hidden} differ from this run's "
                            f"{new_hidden}: init_grow adds inputs and outputs, not hidden units")
    if old_lin[0].in_features != sum(s.stop - s.start for s in init_io.observation.values()):
        raise ParcoverError(f"--init {where}: its actor has {old_lin[0].in_features} inputs, but its env's "
                            f"observation layout (rebuilt from its sidecar) has "
                            f"{sum(s.stop - s.start for s in init_io.observation.values())}")
    if old_lin[-1].out_features != head_outputs(len(init_io.actions), init_io.scan_head):
        raise ParcoverError(f"--init {where}: its actor has {old_lin[-1].out_features} outputs, but its env "
                            f"(rebuilt from its sidecar) has {len(init_io.actions)} action components "
                            f"({head_outputs(len(init_io.actions), init_io.scan_head)} outputs with its "
                            f"{init_io.scan_head} scan head)")
    old_cols, new_cols = [], []
    for name, old in init_io.observation.items():
        new = io.observation.get(name)
        if new is None:
            raise ParcoverError(f"--init {where}: its observation entry {name!r} is not in this run's observation")
        if new.stop - new.start != old.stop - old.start:
            raise ParcoverError(f"--init {where}: observation entry {name!r} has {old.stop - old.start} columns "
                                f"there and {new.stop - new.start} here")
        old_cols += range(old.start, old.stop)
        new_cols += range(new.start, new.stop)
    missing = [a for a in init_io.actions if a not in io.actions]
    if missing:
        raise ParcoverError(f"--init {where}: its action components {missing} are not in this run's {list(io.actions)}")
    old_rows, new_rows = output_rows(init_io), output_rows(io)
    kept = [a for a in init_io.actions if len(old_rows[a]) == len(new_rows[a])]  # same kind of head
    with torch.no_grad():
        old_scale, new_scale = init_net[0], net[0]
        new_scale.centre[new_cols] = old_scale.centre[old_cols]
        new_scale.half_width[new_cols] = old_scale.half_width[old_cols]
        first = new_lin[0]
        first.weight.zero_()
        first.weight[:, new_cols] = old_lin[0].weight[:, old_cols]
        first.bias.copy_(old_lin[0].bias)
        for old, new in zip(old_lin[1:-1], new_lin[1:-1], strict=True):
            new.load_state_dict(old.state_dict())
        last_old, last = old_lin[-1], new_lin[-1]
        last.weight.zero_()
        for rows in new_rows.values():
            if len(rows) == 2:
                last.bias[rows[0]], last.bias[rows[1]] = loc, scale_pre
            else:
                last.bias[rows[0]] = grown_scan_logit(loc, growth.std)
        for name in kept:
            for row_new, row_old in zip(new_rows[name], old_rows[name], strict=True):
                last.weight[row_new] = last_old.weight[row_old]
                last.bias[row_new] = last_old.bias[row_old]
    grown = {"observation": [n for n in io.observation if n not in init_io.observation],
             "actions": [a for a in io.actions if a not in kept]}
    if init_io.scan_head != io.scan_head and "scan" in init_io.actions:
        grown["scan_head"] = f"{init_io.scan_head} -> {io.scan_head}"
    return grown
