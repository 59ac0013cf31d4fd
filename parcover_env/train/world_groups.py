"""``B`` worlds of a scenario or a map pool stepped through the batched stepper, as arrays.

The worlds are ``G`` groups of ``K`` (:class:`WorldsConfig`). Each group runs one map: the group's
``K`` worlds step together in one call of :func:`parcover_env.sim.pipeline.step` (the stepper takes
worlds of one map), so a step of all ``B`` worlds is ``G`` calls, whatever the team sizes. On a map
pool (``generated:A-B``) the agent axis is padded to ``max_robots`` as
:class:`~parcover_env.harness.map_pool.MapPoolEnv` pads it: a padding agent's observation is zeros,
its reward 0, its action ignored, its ``pad`` 1 and ``real`` false.

**Map draws.** A group draws a map of the pool (and one reset seed per world, in world order) from
its own generator when none of its worlds runs any more: a world whose episode ends while others
of its group still run *idles* until they have all ended. An idle world is not stepped; its
observation is zeros, its reward 0, every agent ``pad`` 1 and not ``real`` (out of the loss and of
the agent-step count), and it is neither done nor reset. When the group draws, its idle worlds
start their episodes on the new map at once (the step's next observation is their first), and the
worlds that ended at that very step start in the reset that follows their end (TorchRL's partial
reset). A scenario (or a pool of one map) has one group of all ``B`` worlds and no idling: a world
that ends starts again on the same map with the next seed of the generator.

**Exactness.** Every episode of a world is a fresh copy of the map's env reset with a seed drawn
here: world ``b``'s episode equals, step for step, ``parallel_env(map).reset(seed=episode_seed[b])``
driven with the same actions (the stepper's batched worlds are bit for bit separate envs;
``tests/train/test_world_groups.py``). With a seed (:meth:`WorldGroups.seed`), group ``g``'s
generator is ``default_rng(SeedSequence([seed, g]))``: the same seed gives the same maps, seeds and
transitions, also after a deepcopy or pickle mid-rollout.

``episode_steps`` cuts an episode at that step (truncated, as
:class:`~parcover_env.harness.marl_env.RobotsEnv` does: the env keeps its own step limit, and the
episode's metrics are the KPOIs visited so far, success 0).
"""

from __future__ import annotations

import copy
from dataclasses import dataclass, field
from typing import Any, NamedTuple

import numpy as np

from parcover_env.errors import ConfigError

__all__ = ["METRIC_KEYS", "WorldsConfig", "Transition", "WorldGroups"]

METRIC_KEYS = ("metrics/kpois_visited", "metrics/n_kpois", "metrics/success")
"""The episode metrics kept per agent (non-zero on the step that ends an episode; every agent of a world,
padding too, carries its world's values, as the map pool's infos do)."""


@dataclass(frozen=True)
class WorldsConfig:
    """What :class:`WorldGroups` runs."""

    scenario: str
    """A scenario name (``office``, ``generated:7``, ...) or a map pool ``generated:A-B``."""
    worlds: int = 1
    """``B``: worlds stepped together."""
    worlds_per_map: int = 1
    """``K``: worlds of a group, which run one drawn map at a time (must divide ``worlds``); only a pool
    of more than one map has several groups (a scenario: one group of all worlds)."""
    max_robots: int = 12
    """Agents of a map pool (each map's robots padded to this count)."""
    overrides: dict[str, Any] | None = field(default=None, hash=False)
    """Scenario overrides of every world's env."""
    preset: str = "realistic"
    """Error models of every world's env."""
    episode_steps: int = 0
    """Truncate an episode at this step (0: only the env's own end)."""
    mask_done: bool = False
    """A robot whose own route is done (version 2 ``route_done``) is not ``real`` either."""
    state: bool = False
    """Also ``env.state()`` of every world (MAPPO's critic input; zeros for an idle world)."""
    cache: int = 32
    """Maps of a pool kept built (:class:`~parcover_env.harness.map_pool.MapPoolEnv`'s ``cache``)."""

    def check(self, source: str = "WorldsConfig") -> WorldsConfig:
        """Self, or ConfigError naming ``source`` and the first bad field."""
        for key in ("worlds", "worlds_per_map", "max_robots", "cache"):
            value = getattr(self, key)
            if not isinstance(value, int) or isinstance(value, bool) or value < 1:
                raise ConfigError(source, key, f"must be an integer >= 1, got {value!r}")
        if self.worlds % self.worlds_per_map:
            raise ConfigError(source, "worlds_per_map",
                              f"must divide worlds ({self.worlds}), got {self.worlds_per_map}")
        if not isinstance(self.episode_steps, int) or self.episode_steps < 0:
            raise ConfigError(source, "episode_steps", f"must be an integer >= 0, got {self.episode_steps!r}")
        return self


class Transition(NamedTuple):
    """One step (or reset) of the ``B`` worlds, fresh arrays (never written again)."""

    observation: np.ndarray
    """``(B, N, D)`` float32."""
    reward: np.ndarray
    """``(B, N)`` float32 (0 at a reset, for padding and idle worlds)."""
    terminated: np.ndarray
    """``(B,)`` bool: every KPOI visited this step."""
    truncated: np.ndarray
    """``(B,)`` bool: the env's step limit or ``episode_steps`` reached, not terminated."""
    real: np.ndarray
    """``(B, N)`` bool: a robot of a running world's map (not padding, not idle; with ``mask_done``
    its route is not done)."""
    info: dict[str, np.ndarray]
    """``pad`` and :data:`METRIC_KEYS`, each ``(B, N)`` float32."""
    state: np.ndarray | None
    """``(B, S)`` float32 ``env.state()`` of every world (``WorldsConfig.state``), else None."""


class WorldGroups:
    """The ``B`` worlds of ``cfg`` in groups (see the module docstring); ``seed``: :meth:`seed`."""

    def __init__(self, cfg: WorldsConfig, seed: int | None = None):
        from parcover_env import parallel_env
        from parcover_env.harness.map_pool import MapPoolEnv, is_pool

        self.cfg = cfg.check()
        self.pool = None
        if is_pool(cfg.scenario):
            self.pool = MapPoolEnv(cfg.scenario, cfg.max_robots, overrides=cfg.overrides, preset=cfg.preset,
                                   cache=cfg.cache)
            self.maps: tuple[int, ...] = self.pool.seeds
            first = self.pool.env
            self.n_agents = cfg.max_robots
            self.observation_space = self.pool.observation_space(self.pool.possible_agents[0])
            self.state_space = self.pool.state_space
        else:
            first = parallel_env(cfg.scenario, overrides=cfg.overrides, preset=cfg.preset)
            self.maps = ()
            self.n_agents = first.n_robots
            self.observation_space = first.observation_space(first.possible_agents[0])
            self.state_space = first.state_space
        self.template = first
        """The env every world of a single map copies (a pool's: the first map's; never reset here)."""
        self.action_space = first.action_space(first.possible_agents[0])
        self.per_group = cfg.worlds_per_map if len(self.maps) > 1 else cfg.worlds
        """``K``: worlds per group."""
        self.n_groups = cfg.worlds // self.per_group
        """``G``: groups."""
        b = cfg.worlds
        self.worlds: list[Any] = ([copy.deepcopy(first) for _ in range(b)] if len(self.maps) <= 1
                                  else [None] * b)
        """World ``b``'s env (group ``b // K``); a pool's worlds are made at their group's first draw."""
        self.running = np.zeros(b, dtype=bool)
        """World ``b`` is in an episode (neither ended nor idle)."""
        self.fresh = np.zeros(b, dtype=bool)
        """World ``b`` has a drawn seed its next episode has not started with yet."""
        self.episode_seed = np.full(b, -1, dtype=np.int64)
        """The reset seed of world ``b``'s current (or next, while ``fresh``) episode."""
        self.map_seed = np.full(self.n_groups, self.maps[0] if len(self.maps) == 1 else -1, dtype=np.int64)
        """The pool map (``generated:SEED``) group ``g`` runs (-1 before its first draw; -1 for a scenario)."""
        self.n_robots = np.full(self.n_groups, first.n_robots, dtype=np.int64)
        """Robots of group ``g``'s map."""
        self.draws = np.zeros(self.n_groups, dtype=np.int64)
        """Maps group ``g`` has drawn."""
        self.rngs: list[np.random.Generator] = []
        self.seed(seed)

    # ------------------------------------------------------------------ public
    @property
    def size(self) -> int:
        """``B``."""
        return len(self.worlds)

    def group_of(self, b: int) -> int:
        """The group of world ``b``."""
        return b // self.per_group

    def seed(self, seed: int | None) -> None:
        """Group ``g`` draws from ``default_rng(SeedSequence([seed, g]))`` from now on (unseeded: fresh
        entropy); takes effect at the next draw (a full :meth:`reset` draws for every group)."""
        if seed is not None and (not isinstance(seed, (int, np.integer)) or isinstance(seed, bool) or seed < 0):
            raise ConfigError("WorldGroups", "seed", f"must be None or an integer >= 0, got {seed!r}")
        self.rngs = [np.random.default_rng(None if seed is None else np.random.SeedSequence([int(seed), g]))
                     for g in range(self.n_groups)]

    def reset(self, mask: np.ndarray | None = None) -> Transition:
        """Start episodes: ``mask`` None: every world, each group on a newly drawn map; else the worlds
        where ``mask (B,)`` is true (a running one abandons its episode), on the map their group has drawn
        since they ended (drawn now if none of the group runs), or idle until it draws. Entries of
        unmasked worlds are zeros (the caller keeps what it had)."""
        out = self._blank()
        b_all = self.size
        if mask is None:
            self.running[:] = False
            self.fresh[:] = False
            for g in range(self.n_groups):
                self._draw(g)
            for b in range(b_all):
                self._start(b, out)
            return out
        mask = np.asarray(mask, dtype=bool).reshape(b_all)
        self.running[mask] = False
        for g in range(self.n_groups):
            members = self._members(g)
            chosen = [b for b in members if mask[b]]
            if not chosen:
                continue
            if len(self.maps) <= 1:  # one map: start again at once
                for b in chosen:
                    self.episode_seed[b] = self._seed_draw(g)
                    self.fresh[b] = True
                    self._start(b, out)
                continue
            if not self.running[members].any() and not self.fresh[members].any():
                self._draw(g)
            for b in chosen:
                if self.fresh[b]:
                    self._start(b, out)
        return out

    def step(self, actions: np.ndarray) -> Transition:
        """One step of every running world: ``actions (B, N, A)`` (padding's and idle worlds' rows ignored).
        A group whose worlds have all ended draws its next map here and starts its idle worlds."""
        actions = np.asarray(actions)
        if actions.shape[:2] != (self.size, self.n_agents):
            raise ValueError(f"actions: expected shape ({self.size}, {self.n_agents}, A), got {actions.shape}")
        from parcover_env.sim import pipeline

        cfg, out = self.cfg, self._blank()
        ended_now = np.zeros(self.size, dtype=bool)
        for g in range(self.n_groups):
            idx = [b for b in self._members(g) if self.running[b]]
            if not idx:
                continue
            n = int(self.n_robots[g])
            worlds = [self.worlds[b] for b in idx]
            obs, res = pipeline.step(worlds, actions[idx, :n])
            out.observation[idx, :n] = obs
            out.reward[idx, :n] = res.rewards
            out.info["pad"][idx, :n] = 0.0
            for j, (b, w) in enumerate(zip(idx, worlds, strict=True)):
                term, trunc = bool(res.terminated[j]), bool(res.truncated[j])
                infos = res.infos[j * n:(j + 1) * n]
                if term or trunc:
                    metrics = [float(infos[0][k]) for k in METRIC_KEYS]
                elif cfg.episode_steps and w.steps >= cfg.episode_steps:  # cut here
                    trunc = True
                    visited = np.asarray(w.progress.visited)
                    metrics = [float(visited.sum()), float(visited.size), 0.0]
                else:
                    metrics = None
                if metrics is not None:
                    for key, value in zip(METRIC_KEYS, metrics, strict=True):
                        out.info[key][b] = value
                    ended_now[b] = True
                out.terminated[b], out.truncated[b] = term, trunc
                out.real[b, :n] = True
                if cfg.mask_done:
                    out.real[b, :n] = [info.get("route_done", 0.0) < 0.5 for info in infos]
                if out.state is not None:
                    out.state[b] = w.state()
        self.running[ended_now] = False
        if len(self.maps) > 1:
            for g in range(self.n_groups):
                members = self._members(g)
                if not self.running[members].any() and not self.fresh[members].any():
                    self._draw(g)
                for b in members:
                    if self.fresh[b] and not ended_now[b]:  # an idle world starts on the new map now
                        self._start(b, out)
        return out

    # ------------------------------------------------------------------ helpers
    def _members(self, g: int) -> range:
        return range(g * self.per_group, (g + 1) * self.per_group)

    def _seed_draw(self, g: int) -> int:
        return int(self.rngs[g].integers(2**31))

    def _draw(self, g: int) -> None:
        """Group ``g``'s next map (a pool's: drawn, fresh copies of its env) and one seed per world, in
        world order. A single map keeps its worlds."""
        rng = self.rngs[g]
        if len(self.maps) > 1:
            seed = int(rng.choice(self.maps))
            template = self.pool.map_env(seed)
            self.map_seed[g], self.n_robots[g] = seed, template.n_robots
            for b in self._members(g):
                self.worlds[b] = copy.deepcopy(template)
        for b in self._members(g):
            self.episode_seed[b] = self._seed_draw(g)
            self.fresh[b] = True
        self.draws[g] += 1

    def _start(self, b: int, out: Transition) -> None:
        """World ``b`` resets with its drawn seed; its entries of ``out`` are its first observation."""
        w = self.worlds[b]
        obs, infos = w.reset(seed=int(self.episode_seed[b]))
        self.running[b], self.fresh[b] = True, False
        n = w.n_robots
        out.observation[b, :n] = np.stack([obs[a] for a in w.possible_agents])
        out.info["pad"][b, :n] = 0.0
        out.real[b, :n] = True
        if self.cfg.mask_done:
            out.real[b, :n] = [infos[a].get("route_done", 0.0) < 0.5 for a in w.possible_agents]
        if out.state is not None:
            out.state[b] = w.state()

    def _blank(self) -> Transition:
        """A transition of idle worlds: zeros, every agent padding."""
        b, n = self.size, self.n_agents
        info = {"pad": np.ones((b, n), dtype=np.float32)}
        info.update({k: np.zeros((b, n), dtype=np.float32) for k in METRIC_KEYS})
        state = np.zeros((b, *self.state_space.shape), dtype=np.float32) if self.cfg.state else None
        return Transition(np.zeros((b, n, *self.observation_space.shape), dtype=np.float32),
                          np.zeros((b, n), dtype=np.float32), np.zeros(b, dtype=bool), np.zeros(b, dtype=bool),
                          np.zeros((b, n), dtype=bool), info, state)
