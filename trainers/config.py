"""Configuration of both learners: ``Config`` (MA-POCA) and ``PPOConfig`` (PPO-PCGRL), frozen
dataclasses whose shared hyper-parameters have the same names; one presets table ``PRESETS``
(learner -> preset -> config); one loader ``load_config`` (preset, then a JSON file, then
overrides; every bad field a one-line ``ValueError`` naming it). Runs save their config in their
run folder and in every checkpoint; ``from_dict`` reads it back.

MA-POCA's units: ``n_arenas x n_steps`` environment *decisions* (every player acts once) per update;
each decision holds up to ``P = 3`` agent experiences. ML-Agents counts its buffer, batch and
``max_steps`` in agent experiences; ``from_agent_steps`` converts them (the ``paper`` preset).
"""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

from raidjax import content, pcg, validate
from raidjax.types import SENSES
from raidjax.validate import check_fields, is_number
from trainers.returns import EPISODE_ENDS

NETWORKS = ("raidjax", "reference")  # Config.network
# The largest total_steps: counters of decisions (and the PPO's edits) are int32 inside the programs.
MAX_STEPS = 2**31 - 1


@dataclasses.dataclass(frozen=True)
class Config:
    """Hyper-parameters (hashable, so it can be a static argument).

    Attributes:
        n_arenas: parallel arenas (auto-resetting) per seed.
        n_steps: rollout length per update (the λ-return horizon; bootstrap at its end).
        n_minibatches: minibatches per epoch (minibatch = n_arenas * n_steps / n_minibatches decisions).
        update_epochs: passes over each rollout.
        lr, anneal_lr: Adam learning rate; linear decay to 0 over the run if ``anneal_lr``.
        adam_eps: Adam's epsilon (torch's default 1e-8 in ML-Agents; 1e-5 the PureJaxRL habit).
        max_grad_norm: global gradient-norm clip (0 disables).
        gamma, lam: discount and λ of the λ-returns.
        clip_eps: PPO ratio clip ε, also the value/baseline clip.
        ent_coef, anneal_ent: entropy bonus β (linear decay to 0 if ``anneal_ent``).
        hidden, layers, heads: network width, MLP depth, attention heads (actor and critic).
        proj_attention: the actor attends over projectiles as entities (else they join its
            self features; cheaper on CPU). raidjax's senses only: the reference senses see
            projectiles through rays, so with ``senses="reference"`` it has no effect.
        bf16: mixed precision: the networks' layers compute in bfloat16 (parameters, attention
            softmaxes, outputs, losses and Adam stay float32; ``trainers.networks``). Meant for
            GPUs; on CPUs without bfloat16 units it is slower.
        skill_ranges: skill-slot-1 range of every player, drawn from this set (one draw per arena,
            shared by its players).
        content_box: train over the content generator's whole box instead: every arena draws the
            generator's parameters (``parameters``; by default the paper's four: the players'
            skill slot 1 range, cool time, cast time and coefficient) uniformly within their
            bounds, on the generator's base content (``raidjax.pcg.base_game(players)``), at the
            ``redraw_every`` cadence; ``skill_ranges`` is then unused. The observation carries
            the players' skills (range, damage, cast time; cool time through the recharge timer),
            so one network can play every skill the generator makes; stats only show through
            their effects (HP fractions).
        players: the team's class presets (``raidjax.catalogue.CLASSES``), e.g. a mixed team
            ``("warrior", "mage", "priest")``; one network plays every member, which tells the
            classes apart by their observed skills.
        parameters: the box of ``content_box`` (``raidjax.pcg.space`` names; empty = the paper's
            four, which need three mages).
        redraw_every: an arena draws a new range at its start and then after every
            ``redraw_every``-th episode (2 = the reference, ``MMORPGEnvController.ResetScene``:
            episodes 1-2, 3-4, ... share a range; 1 = every episode).
        fresh_starts: in training only, the probability that an arena's next episode starts
            fresh (``raidjax.reset``) instead of inheriting what the rules carry across an
            episode's end (``raidjax.next_episode``). 0 = the reference's chained arenas. Under
            the reference rules a game's start depends on how the previous one went (docs/GAME.md,
            "What a game hands on to the next"); fresh starts make the start independent of it.
            Evaluation always chains.
        random_spawns: in training only, every episode draws its spawns (``EnvConfig.random_spawns``:
            positions and headings), so a team cannot learn one opening by heart; evaluation plays
            the content as given (the reference's fixed spawns).
        minibatch_rows: what a minibatch's samples are: ``"decisions"`` (a decision with its
            players; ``n_minibatches`` divides ``n_arenas * n_steps``) or ``"agents"`` (one player's
            experience in one decision, as ML-Agents' buffer rows are: ``n_minibatches`` divides
            ``n_arenas * n_steps * P`` rows, the live ones taken first in a random order each
            epoch, and a minibatch is skipped unless every row in it is live, as ML-Agents drops
            the rows past ``len // batch_size`` minibatches). The value loss is then over rows
            whatever ``episode_ends`` says, and ``anneal_lr`` counts the minibatches taken.
        network: the networks' layout (``trainers.networks`` / ``trainers.reference_networks``):
            ``"raidjax"`` (ReLU layers, the entity embeddings ``hidden`` wide, attention without a
            LayerNorm after its residual and logits ÷ √(head width), a flat critic input per agent,
            the agent count before the critic's body, flax's initial weights) or ``"reference"``
            (ML-Agents 0.28's POCA networks layer by layer: Swish, a 128-wide observation encoder
            with its own attention in the actor and in the critic for every agent, LayerNorm after
            the residual, logits ÷ √(width), the count after the critic's body, ML-Agents' initial
            weights; the ``paper`` preset).
        episode_ends: how a game's end reaches the λ-returns (``trainers.returns``): ``"reference"``
            (ML-Agents 0.28 POCA on the reference build: a win and a timeout bootstrap from the
            final observation's value, a loss does not, a player who dies while its teammates fight
            on ends its own trajectory with a bootstrap; value loss over agent experiences),
            ``"win_bootstrapped"`` (a win bootstraps; a death does not end a player's trajectory)
            or ``"terminal"`` (a win and a loss are terminal: raidjax's learner before 2026-11-29).
        total_steps: environment decisions per seed.
        updates_per_chunk: updates per jitted chunk (one log row / progress line per chunk).
        checkpoint_every: checkpoint every this many updates (rounded up to whole chunks).
        eval_games: games of the final evaluation (and of PT-HR on the same content).
        deterministic_eval: evaluate the greedy (argmax) policy instead of sampling.
        stale_phases: ``K``; above 1, the reference trainer's asynchronous data approximated
            (``trainers.windows``): ``K`` groups of ``n_arenas`` arenas each act ``n_steps / K``
            decisions per update, and an update trains on the one group whose ``n_steps``-decision
            window it completes, acted by the last ``K`` updates' policies. 1: every update's
            rollout is acted by its own policy.
        senses: what the players observe and how they act (``raidjax.with_senses``):
            ``"raidjax"`` (raidjax's observation, 10 masked actions) or ``"reference"`` (the
            reference player's 204-float observation and 8 unmasked actions; the ``paper`` preset).
            The trained team's ``TeamPolicy`` plays every content with the same senses.
    """

    # rollout
    n_arenas: int = 256
    n_steps: int = 32
    # optimisation (PPO with the POCA baseline)
    n_minibatches: int = 4
    update_epochs: int = 3
    lr: float = 3e-4
    anneal_lr: bool = True
    adam_eps: float = 1e-5
    max_grad_norm: float = 0.5
    gamma: float = 0.99
    lam: float = 0.95
    clip_eps: float = 0.2
    ent_coef: float = 0.01
    anneal_ent: bool = False
    # networks
    hidden: int = 64
    layers: int = 2
    heads: int = 4
    proj_attention: bool = True
    bf16: bool = False
    # content and team
    skill_ranges: tuple[float, ...] = (13.0,)
    content_box: bool = False
    players: tuple[str, ...] = ("mage", "mage", "mage")
    parameters: tuple[str, ...] = ()
    redraw_every: int = 2
    fresh_starts: float = 0.0
    random_spawns: bool = False
    senses: str = "raidjax"
    network: str = "raidjax"
    minibatch_rows: str = "decisions"
    episode_ends: str = "reference"
    stale_phases: int = 1
    # run length, checkpoints and the final evaluation
    total_steps: int = 1_000_000
    updates_per_chunk: int = 10
    checkpoint_every: int = 50
    eval_games: int = 500
    deterministic_eval: bool = False

    @property
    def decisions_per_update(self) -> int:
        """Environment decisions per update and seed."""
        return self.n_arenas * self.n_steps

    @property
    def num_updates(self) -> int:
        """Updates per seed: ``total_steps`` rounded up to whole updates and whole chunks."""
        n = -(-self.total_steps // self.decisions_per_update)
        return -(-n // self.updates_per_chunk) * self.updates_per_chunk

    @property
    def num_chunks(self) -> int:
        """Jitted chunks per run."""
        return self.num_updates // self.updates_per_chunk

    def __post_init__(self):
        check_fields(self, {
            **dict.fromkeys(("n_arenas", "n_steps", "n_minibatches", "update_epochs", "hidden", "layers", "heads",
                             "redraw_every", "updates_per_chunk", "checkpoint_every", "stale_phases"), (1, None)),
            "total_steps": (1, MAX_STEPS),
            "eval_games": (0, None), "lr": (0, None, "> 0"), "adam_eps": (0, None, "> 0"),
            "max_grad_norm": (0, None), "gamma": (0, 1), "lam": (0, 1), "clip_eps": (0, None, "> 0"),
            "ent_coef": (0, None), "fresh_starts": (0, 1)})
        ranges = self.skill_ranges
        if (isinstance(ranges, str | bytes) or not hasattr(ranges, "__len__") or not len(ranges)
                or not all(is_number(r) and 1 <= r <= 20 for r in ranges)):
            raise ValueError(f"skill_ranges: value {ranges!r}; allowed: a non-empty list of numbers in [1, 20]")
        object.__setattr__(self, "skill_ranges", tuple(float(r) for r in ranges))  # JSON lists -> hashable
        for name in ("players", "parameters"):
            value = getattr(self, name)
            if isinstance(value, str) or not isinstance(value, tuple | list) or not all(
                    isinstance(v, str) for v in value):
                raise ValueError(f"{name}: value {value!r}; allowed: a list of names")
            object.__setattr__(self, name, tuple(value))
        content.player_names(self.players)
        if self.content_box:
            pcg.make_space(self.parameters, self.players)  # ValueError naming a bad parameter
        validate.name("senses", self.senses, SENSES, "observation and action space")
        validate.name("episode_ends", self.episode_ends, EPISODE_ENDS, "way a game's end reaches the returns")
        validate.name("network", self.network, NETWORKS, "network layout")
        validate.name("minibatch_rows", self.minibatch_rows, ("decisions", "agents"), "kind of sample")
        agents = self.minibatch_rows == "agents"
        rows = self.n_arenas * self.n_steps * (len(self.players) if agents else 1)
        if rows % self.n_minibatches:
            what = "agent experiences per update (n_arenas * n_steps * players)" if agents else \
                "decisions per update (n_arenas * n_steps)"
            raise ValueError(f"n_minibatches: value {self.n_minibatches}; allowed: a divisor of the {rows} {what}")
        if self.n_steps % self.stale_phases:
            raise ValueError(f"stale_phases: value {self.stale_phases}; allowed: a divisor of n_steps = {self.n_steps}")
        if self.hidden % self.heads:
            raise ValueError(f"heads: value {self.heads} must divide hidden = {self.hidden}")
        if self.network == "reference" and self.heads != 4:
            raise ValueError(f"heads: value {self.heads}; allowed with network 'reference': 4 (ML-Agents' attention "
                             "has 4 heads, no setting changes it)")

    def replace(self, **kw) -> Config:
        """A copy with fields changed (checked again); an unknown field raises ``ValueError`` naming it."""
        return dataclasses.replace(self, **known_fields(Config, kw))

    def to_dict(self) -> dict:
        """JSON-able dict of every field."""
        d = dataclasses.asdict(self)
        d["skill_ranges"] = list(self.skill_ranges)
        return d

    @classmethod
    def from_dict(cls, d: dict) -> Config:
        """Inverse of ``to_dict``; raises ``ValueError`` naming unknown keys."""
        return cls().replace(**known_fields(cls, d))


def known_fields(cls, d: dict) -> dict:
    """``d`` unchanged if every key is a field of the dataclass ``cls``; else ``ValueError``
    naming the unknown keys and the known ones (both trainers' ``from_dict``)."""
    known = {f.name for f in dataclasses.fields(cls)}
    unknown = sorted(set(d) - known)
    if unknown:
        raise ValueError(f"config: unknown keys {unknown}; known: {sorted(known)}")
    return d


def from_agent_steps(buffer: int, batch: int, horizon: int, players: int = 3) -> tuple[int, int]:
    """``(n_arenas, n_minibatches)`` of an update holding ML-Agents' buffer, with minibatches of
    agent experiences (``minibatch_rows="agents"``).

    ML-Agents updates once its buffer holds *more than* ``buffer`` agent experiences
    (``poca/trainer.py``: ``num_experiences > buffer_size``), filled with trajectories of
    ``horizon`` steps per agent, and takes ``len // batch`` minibatches of ``batch`` agent
    experiences per epoch. With every player alive a decision is ``players`` experiences, so
    ``n_arenas = buffer // (horizon * players) + 1`` arenas of ``horizon`` decisions are the
    first whole number of trajectories past ``buffer`` (8192, 256, 256, 3: 11 arenas = 8448
    experiences = 33 trajectories), and ``n_minibatches`` is the divisor of those experiences
    nearest to ``8448 // 256 = 33`` (ties: the smaller): 33 minibatches of 256, as ML-Agents takes.
    """
    n_arenas = buffer // (horizon * players) + 1
    rows = n_arenas * horizon * players
    want = rows // batch
    divisors = [d for d in range(1, rows + 1) if rows % d == 0]
    return n_arenas, min(divisors, key=lambda d: (abs(d - want), d))


PAPER_AGENT_STEPS = 50_000_000  # max_steps of configuration_range5.yaml, in agent steps
_PAPER_ARENAS, _PAPER_MINIBATCHES = from_agent_steps(buffer=8192, batch=256, horizon=256)

_MAPOCA_PRESETS = {
    # The reference trainer (Experiment/MA/RL_HEURISTIC/configs/configuration_range5.yaml, ML-Agents
    # 0.28 POCA), field by field: buffer 8192 and batch 256 agent experiences (from_agent_steps:
    # 11 arenas x 256 decisions, 33 minibatches of 256 agent experiences), time_horizon 256, 3 epochs, 2 x 256 hidden, 4
    # heads, lr 3e-4 and beta 0.01 constant (the yaml sets every schedule to constant), epsilon
    # 0.2, lambda 0.95, gamma 0.99, torch Adam (eps 1e-8), no gradient clipping, max_steps 5e7
    # agent steps = 5e7 / 3 decisions with all players alive, the reference player's senses
    # (its observation and its 8 actions), ML-Agents' networks (reference_networks), a game's end as
    # the reference trainer's (returns.py). Differences left: docs/PROTOCOLS.md §12.
    "paper": Config(n_arenas=_PAPER_ARENAS, n_steps=256, n_minibatches=_PAPER_MINIBATCHES, update_epochs=3,
                    lr=3e-4, anneal_lr=False, adam_eps=1e-8, max_grad_norm=0.0, hidden=256, layers=2, heads=4,
                    ent_coef=0.01, anneal_ent=False, lam=0.95, gamma=0.99, clip_eps=0.2,
                    total_steps=-(-PAPER_AGENT_STEPS // 3), redraw_every=2, senses="reference", network="reference",
                    minibatch_rows="agents", episode_ends="reference"),
    # Chosen by a measured sweep on the reference senses (docs/results/benchmark1.md, "Choosing the
    # cpu preset"): 256 arenas x 32 decisions per update amortise the step on a 2-core CPU; a 2 x 64
    # network with teammate-only attention (projectiles join the self features); 3 epochs of 32
    # minibatches of 256 decisions at a constant lr 3e-4 (6x the Adam steps per decision of the
    # earlier 2 epochs x 8 minibatches at 1e-3, closer to the reference trainer's); entropy bonus 0.003, which lets
    # the sampled policy sharpen (0.01 kept it near-uniform over the reference's 8 unmasked actions).
    # A win is terminal here (episode_ends "terminal", not the reference trainer's "reference"): at this
    # budget the ablation (docs/results/ablation.md; reference senses, ranges 9 and 13, 3 seeds, 1.5 M
    # decisions) found today's ends winning more under the reference rules (0.652 / 0.929 against
    # 0.394 / 0.674) and below PT-HR at fewer chain positions (11 of 60 against 37); on three held-out
    # seeds it and the runner-up (the reference optimiser) are even under the reference rules and it
    # plays better without the carry at range 13.
    "cpu": Config(n_arenas=256, n_steps=32, n_minibatches=32, update_epochs=3, lr=3e-4, anneal_lr=False, hidden=64,
                  layers=2, heads=2, proj_attention=False, ent_coef=0.003, lam=0.95, gamma=0.99, clip_eps=0.2,
                  updates_per_chunk=5, episode_ends="terminal"),
}


@dataclasses.dataclass(frozen=True)
class PPOConfig:
    """PPO and generator-environment settings (hashable, so it can be a static argument).

    The names shared with ``Config`` (MA-POCA) mean the same: ``n_arenas`` parallel environments
    (here generator episodes), ``n_steps`` rollout length per update, ``lam`` the λ of GAE,
    ``hidden`` and ``layers`` the width and depth of the MLPs (actor and critic), and so on.
    """

    n_arenas: int = 32  # generator episodes stepped in parallel
    n_steps: int = 8  # rollout horizon per update
    total_steps: int = 20480  # generator steps (edits) over all arenas
    update_epochs: int = 8  # samples are expensive (each is 50 games): reuse them more
    n_minibatches: int = 4
    lr: float = 2e-3
    anneal_lr: bool = True
    gamma: float = 0.95
    lam: float = 0.9
    clip_eps: float = 0.2
    ent_coef: float = 0.003
    vf_coef: float = 0.5
    max_grad_norm: float = 0.5
    hidden: int = 64
    layers: int = 2
    reward_scale: float = 0.1  # the env pays x100 per unit of win rate; the learner sees x10
    edit_cost: float = 0.0  # learner-side penalty per tick moved (env reward units); 0 = off
    n_games: int = 50  # playtest games per training measurement
    target: tuple = (0.05, 0.75)  # (low, high) sampled per episode; (t, t) for a fixed target
    observe_target: bool = True
    strict_length: bool = False
    max_edits: int = 40
    pool_repeats: bool = False  # env: re-measuring an unchanged skill pools its games (pcg.PCGParams)
    # A style goal: the env draws a goal at one end of ``goal_axis`` per episode (pcg.PCGParams.goal_axis;
    # (1, 1, 1, 1) = heavy vs light skills) and the learner pays goal_cost per unit change of the squared
    # distance to it in ticks, which telescopes to goal_cost * (d^2(final) - d^2(start)): the generator is
    # paid to end near its goal, spreading its skills along the axis. None / 0 = off.
    goal_axis: tuple | None = None
    goal_cost: float = 0.0
    # The edited parameters (raidjax.pcg.space names, e.g. ("skill1.range", "boss.max_hp=500:3000")) and
    # the team's class presets; () = the paper's four on three mages.
    parameters: tuple[str, ...] = ()
    players: tuple[str, ...] = ("mage", "mage", "mage")

    def __post_init__(self):
        check_fields(self, {
            **dict.fromkeys(("n_arenas", "n_steps", "update_epochs", "n_minibatches", "n_games",
                             "max_edits", "hidden", "layers"), (1, None)),
            "total_steps": (1, MAX_STEPS),
            **dict.fromkeys(("lr", "clip_eps", "reward_scale"), (0, None, "> 0")),
            "gamma": (0, 1), "lam": (0, 1),
            **dict.fromkeys(("ent_coef", "vf_coef", "max_grad_norm", "edit_cost", "goal_cost"), (0, None))})
        for name in ("parameters", "players"):  # JSON gives lists; static fields must be hashable
            value = getattr(self, name)
            if not isinstance(value, tuple | list) or not all(isinstance(v, str) for v in value):
                raise ValueError(f"{name}: value {value!r}; allowed: a list of names")
            object.__setattr__(self, name, tuple(value))
        content.player_names(self.players)
        target = self.target
        if (not isinstance(target, tuple | list) or len(target) != 2 or not all(is_number(x) for x in target)
                or not 0 <= target[0] <= target[1] <= 1):
            raise ValueError(f"target: value {target!r}; allowed: (low, high) win rates with 0 <= low <= high <= 1")
        object.__setattr__(self, "target", tuple(float(x) for x in target))  # JSON gives a list
        space = self.space  # checks the names against the team (ValueError naming the parameter)
        if self.goal_axis is not None:  # JSON gives a list; the env needs a hashable static field
            object.__setattr__(self, "goal_axis", pcg.goals.check_axis(self.goal_axis, space.size))
        if (self.goal_axis is None) != (self.goal_cost == 0):
            raise ValueError(f"goal_cost: value {self.goal_cost} with goal_axis {self.goal_axis}: a style goal "
                             "needs both (goal_cost > 0 and an axis such as (1, 1, 1, 1)), or neither")
        batch = self.n_arenas * self.n_steps
        if batch % self.n_minibatches:
            raise ValueError(f"n_minibatches: value {self.n_minibatches}; allowed: a divisor of n_arenas * n_steps "
                             f"= {batch}")

    @property
    def widths(self) -> tuple[int, ...]:
        """The MLPs' layer widths, ``(hidden,) * layers``."""
        return (self.hidden,) * self.layers

    @property
    def space(self) -> pcg.Space:
        """The edited parameters (``raidjax.pcg.make_space``: ``parameters`` for ``players``, or the paper's four)."""
        return pcg.make_space(self.parameters, self.players)

    @property
    def num_updates(self) -> int:
        """PPO updates per run (at least 1)."""
        return max(1, self.total_steps // (self.n_arenas * self.n_steps))

    def replace(self, **kw) -> PPOConfig:
        """A copy with fields changed (checked again); an unknown field raises ``ValueError`` naming it."""
        return dataclasses.replace(self, **known_fields(PPOConfig, kw))

    def to_dict(self) -> dict:
        """JSON-able dict of every field."""
        return dataclasses.asdict(self)

    @classmethod
    def from_dict(cls, d: dict) -> PPOConfig:
        """Inverse of ``to_dict`` (JSON lists become tuples; a config saved before ``layers`` existed,
        ``hidden`` a list of equal widths, is read as ``hidden`` and ``layers``); raises ``ValueError``
        naming unknown keys or a bad value."""
        d = upgrade_ppo_fields(d)
        return cls(**{k: tuple(v) if isinstance(v, list) else v for k, v in known_fields(cls, d).items()})


_PPO_PRESETS = {
    # The reference run (GAME.md §10): batch 16, buffer 120, lr 3e-4, entropy 0.005, clip 0.2, λ 0.99,
    # 3 epochs, 4 x 256, γ 0.99, horizon 30, 20 000 steps; one model per target, target not observed.
    "paper": PPOConfig(n_arenas=4, n_steps=30, total_steps=20_000, update_epochs=3, n_minibatches=8, lr=3e-4,
                       anneal_lr=False, gamma=0.99, lam=0.99, clip_eps=0.2, ent_coef=0.005,
                       hidden=256, layers=4, reward_scale=1.0, n_games=100, observe_target=False),
    # One model for all targets (target and last win rate observed), many parallel episodes.
    "cpu": PPOConfig(),
}



PRESETS: dict[str, dict[str, Config | PPOConfig]] = {"mapoca": _MAPOCA_PRESETS, "ppo_pcgrl": _PPO_PRESETS}
LEARNERS = {"mapoca": Config, "ppo_pcgrl": PPOConfig}


def upgrade_ppo_fields(d: dict) -> dict:
    """PPO-PCGRL fields saved before ``layers`` existed (``hidden`` a list of widths) as they are
    read today: ``hidden`` the width and ``layers`` the count; unequal widths raise ``ValueError``."""
    h = d.get("hidden")
    if not isinstance(h, list | tuple):
        return d
    if not h or len(set(h)) != 1 or "layers" in d:
        raise ValueError(f"hidden: value {list(h)!r}; allowed: a whole number (the width; layers: the depth)")
    return {**d, "hidden": h[0], "layers": len(h)}


def upgrade_settings(settings: dict) -> dict:
    """A run folder's saved settings as today's code writes them (``upgrade_ppo_fields`` on every
    nested PPO-PCGRL config: a dict with ``n_games`` and ``reward_scale``)."""
    out = {k: upgrade_settings(v) if isinstance(v, dict) else v for k, v in settings.items()}
    return upgrade_ppo_fields(out) if {"n_games", "reward_scale"} <= set(out) else out


def read_fields(path: str | Path, kind: str) -> dict:
    """The JSON object in the file ``path`` (a dict of ``kind`` fields, unchecked); raises
    ``ValueError`` naming the file and what is wrong when it is unreadable or not an object."""
    try:
        data = json.loads(Path(path).read_text())
    except (OSError, json.JSONDecodeError) as e:
        raise ValueError(f"config: cannot read {path} as a JSON object of {kind} fields ({e})") from None
    if not isinstance(data, dict):
        raise ValueError(f"config: {path} holds a {type(data).__name__}; allowed: a JSON object of {kind} fields")
    return data


def load_config(preset: str = "cpu", path: str | Path | None = None, *, learner: str = "mapoca",
                **overrides) -> Config | PPOConfig:
    """``PRESETS[learner][preset]``, then the JSON file at ``path`` (a dict of fields), then
    ``overrides`` (``None`` skipped).

    Args:
        preset: ``"paper"`` or ``"cpu"``. path: a JSON object of config fields, or ``None``.
        learner: ``"mapoca"`` (returns a ``Config``) or ``"ppo_pcgrl"`` (a ``PPOConfig``).

    Raises:
        ValueError: unknown learner or preset, an unreadable file, unknown keys or bad values
            (one line each, naming the field).
    """
    validate.name("learner", learner, tuple(PRESETS), "learner")
    if preset not in PRESETS[learner]:
        raise ValueError(f"preset: unknown {preset!r}; known: {sorted(PRESETS[learner])}")
    cls, cfg = LEARNERS[learner], PRESETS[learner][preset]
    if path is not None:
        data = read_fields(path, cls.__name__)
        cfg = cls.from_dict({**cfg.to_dict(), **(upgrade_ppo_fields(data) if learner == "ppo_pcgrl" else data)})
    return cfg.replace(**{k: v for k, v in overrides.items() if v is not None})
