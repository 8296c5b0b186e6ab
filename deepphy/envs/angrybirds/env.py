"""Angry Birds: launch the level's birds, in their fixed order, until every pig is dead.

On the fly: one decision = one launch of the bird in the slingshot; the scene is then
simulated until it is at rest (sim.py) and the next observation shows it. An attempt ends
when every pig is dead (success) or when the birds run out (the level is lost): both are
`terminated`, an outcome of the game (no budget of the harness cut it short); it has at
most as many decisions as the level has birds. One attempt per level.

Score: SCORE_PIG per pig killed, SCORE_BLOCK per block destroyed and, when the level is
won, SCORE_UNUSED_BIRD per bird not launched. Stars (on the last step): 0 when lost, else
1, 2 or 3 by the birds used against the oracle's plan (levels.stars_for); the prompt states
the rule in words, and nothing shown states the oracle's bird count. Every step carries the
score so far; `info` has the shot's details.

By default the model gets what the paper's prompt gave: the picture, the birds in order
with their abilities in words, the action syntax, the stars' rule, and the score as the
game displays it (points and bonuses as they are won). Option `state_text` (the shared one) adds the numbers deepphy gave before
parity: the picture's size, the abilities' times and damage factors, the score's points.
Option `physics_hints` (an ablation): the observation names the level's title and the
prompt adds the ballistics (gravity, launch speed per unit of power, the picture's scale
and launch pixel).
"""

from __future__ import annotations

from deepphy.envs.angrybirds import SPEC
from deepphy.envs.angrybirds import constants as C
from deepphy.envs.angrybirds.levels import Level, level_ids, load_level
from deepphy.envs.angrybirds.render import render
from deepphy.envs.angrybirds.sim import ShotResult, World
from deepphy.envs.angrybirds.space import Shoot, ShootSpace
from deepphy.envs.base import FILM_FPS, Action, EnvOptions, Environment, Frame, Observation, StepResult, Task
from deepphy.envs.images import Image, stack_frames

FLIGHT_FRAMES = 4  # frames in the strip of a shot's flight


class AngryBirdsOptions(EnvOptions):
    physics_hints: bool = False  # the ballistics constants and the level's title (an ablation)


class AngryBirdsEnv(Environment):
    spec = SPEC
    Options = AngryBirdsOptions

    def __init__(self, options: AngryBirdsOptions | None = None) -> None:
        super().__init__(options)
        self._level: Level | None = None
        self._world: World | None = None
        self._shots = 0
        self._trails: list = []
        self._film_every: float | None = None  # set while `film` steps: the shot keeps a replay's pictures
        self._last_shot: ShotResult | None = None

    @classmethod
    def tasks(cls, options) -> list[Task]:
        out = []
        for level_id in level_ids():
            level = load_level(level_id)
            out.append(Task(env=SPEC.name, id=level_id, group=level.group,
                            params={"birds": len(level.birds), "pigs": len(level.pigs),
                                    "physics_hints": options.physics_hints, "state_text": options.state_text}))
        return out

    @property
    def world(self) -> World | None:
        """The simulated world of the attempt in progress (privileged: for the shortcut
        baselines and tools, never shown to a model)."""
        return self._world

    # -- the contract ---------------------------------------------------------------

    def reset(self, task: Task) -> Observation:
        self._level = load_level(task.id)
        self._world = World(self._level)
        self._shots = 0
        self._trails = []
        scene = self._scene("scene", "The level before the first shot.")
        return self._observation(scene)

    def step(self, action: Action) -> StepResult:
        assert isinstance(action, Shoot) and self._world is not None and self._level is not None
        level, world = self._level, self._world
        if self._shots >= len(level.birds) or world.pigs_left == 0:
            raise RuntimeError("the attempt is over: reset() first")
        bird = level.birds[self._shots]
        shot = self._last_shot = world.shoot(bird, action.angle, action.power, record=True, film_every=self._film_every)
        self._shots += 1
        self._trails = shot.trails
        won = world.pigs_left == 0
        done = won or self._shots >= len(level.birds)
        score = world.score(self._shots)
        stars = level.stars(won, self._shots) if done else None

        feedback = self._describe(shot, action, won, done, score, stars)
        settled = self._scene(f"shot_{self._shots}",
                              f"the scene at rest after shot {self._shots}, with the bird's trail as white dots")
        flight = Image.from_array(f"shot_{self._shots}_flight",
                                  f"the flight of shot {self._shots} ({C.BIRD_NAMES[bird]}), left to right in time",
                                  self._flight_strip(shot))
        info = {
            "shots_used": self._shots,
            "bird": bird,
            "pigs_killed": shot.pigs_killed,
            "blocks_destroyed": shot.blocks_total,
            "pigs_left": world.pigs_left,
            "first_hit": shot.first_hit,
            "ability": shot.ability,
            "sim_time": round(shot.sim_time, 3),
            "at_rest": shot.at_rest,
        }
        if done:
            info["birds_unused"] = len(level.birds) - self._shots if won else 0
        return StepResult(
            terminated=done,  # won, or out of birds: the level is lost
            success=won,
            observation=None if done else self._observation(settled),
            feedback=feedback,
            key_frames=[flight, settled],
            stars=stars,
            score=float(score),
            info=info,
        )

    def film(self, action: Action) -> tuple[StepResult, list[Frame]]:
        """`step`, with the shot's flight and the scene settling, FILM_FPS pictures per
        simulated second (the same simulation: the shot only keeps more snapshots)."""
        self._film_every = 1 / FILM_FPS
        try:
            result = self.step(action)
        finally:
            self._film_every = None
        waiting, shot = self._waiting(), self._last_shot
        return result, [Frame(render(self._level, s.poses, waiting=waiting, trails=s.trails, blasts=s.blasts),
                              f"t = {s.t:.2f} s of shot {self._shots}") for s in shot.film]

    # -- pictures and words ---------------------------------------------------------

    def _waiting(self) -> list[str]:
        return list(self._level.birds[self._shots:])

    def _scene(self, name: str, caption: str) -> Image:
        img = render(self._level, self._world.poses(), waiting=self._waiting(), trails=self._trails)
        return Image.from_array(name, caption, img)

    def _flight_strip(self, shot: ShotResult):
        snaps = shot.snapshots
        end = snaps[-1].t
        hit = shot.first_hit_time if shot.first_hit_time is not None else end
        times = [0.5 * hit, hit, hit + 0.6, hit + 1.6]
        chosen = [min(snaps, key=lambda s: abs(s.t - t)) for t in times]
        blast = next((s for s in snaps if s.blasts), None)
        if blast is not None and blast not in chosen:  # always show the explosion
            k = min(range(len(chosen)), key=lambda i: abs(chosen[i].t - blast.t))
            chosen[k] = blast
        chosen = sorted({id(s): s for s in chosen}.values(), key=lambda s: s.t)
        waiting = self._waiting()
        frames = [render(self._level, s.poses, waiting=waiting, trails=s.trails, blasts=s.blasts) for s in chosen]
        return stack_frames(frames, [f"t = {s.t:.1f} s" for s in chosen], height=270)

    def _observation(self, scene: Image) -> Observation:
        level, world = self._level, self._world
        waiting = self._waiting()
        after = ", ".join(waiting[1:]) if len(waiting) > 1 else "none (this is the last bird)"
        hints = self.options.physics_hints  # type: ignore[attr-defined]
        lines = [
            f"Level {level.id}: {level.title}." if hints else f"Level {level.id}.",
            f"Bird in the slingshot: the {C.BIRD_NAMES[waiting[0]]} "
            f"(shot {self._shots + 1} of at most {len(level.birds)}).",
            f"Birds after it, in order: {after}.",
            f"Pigs left: {world.pigs_left}.",
            f"Shots used: {self._shots}. Score so far: {world.score(self._shots)}.",
        ]
        return Observation(images=[scene], text="\n".join(lines), action_space=ShootSpace())

    def _describe(self, shot: ShotResult, action: Shoot, won: bool, done: bool, score: int, stars: int | None) -> str:
        level, world = self._level, self._world
        parts = [f"Shot {self._shots} ({C.BIRD_NAMES[shot.bird]}, {ShootSpace().format(action)})"]
        if shot.first_hit:
            parts.append(f"first hit: {shot.first_hit}")
        elif shot.birds_left_world:
            parts.append("it touched nothing and flew out of the picture")
        else:
            parts.append("it touched nothing")
        if shot.ability:
            parts.append(shot.ability)
        parts.append(f"pigs killed: {shot.pigs_killed}")
        if shot.blocks_destroyed:
            kinds = ", ".join(f"{n} {m}" for m, n in sorted(shot.blocks_destroyed.items()))
            parts.append(f"blocks destroyed: {shot.blocks_total} ({kinds})")
        else:
            parts.append("blocks destroyed: 0")
        parts.append(f"pigs left: {world.pigs_left}")
        parts.append(f"score so far: {score}")
        text = "; ".join(parts) + "."
        if won:
            spare = len(level.birds) - self._shots
            saved = (f"with {spare} bird(s) to spare (+{C.SCORE_UNUSED_BIRD * spare})" if spare
                     else "with the last bird (no bonus for spare birds)")
            text += f" Every pig is dead: level won {saved}; final score {score}, {stars} star(s)."
        elif done:
            text += f" No birds left and {world.pigs_left} pig(s) still standing: level lost."
        return text
