"""Cut the Rope: 88 levels of our own design, played headless on pymunk, scored by the game.

An attempt: the model sees the screenshot and the text state, chooses one action; the
world, paused while it thinks, applies the action and then runs ACTION_INTERVAL seconds
(sleep(s) runs s seconds instead), and the model sees the result. The game decides the
outcome: won when Om Nom eats the candy, lost when the candy leaves the screen, touches a
hazard or a spider reaches it. success(), fail() and the 10th action end the decisions: the world
then runs on for up to RUN_ON_CAP seconds to decide (undecided after success(): a false
claim, scored as a loss; undecided after the 10th action: truncated). fail() stops acting
too: the world runs on and the game decides (a candy already on its way still wins).
Stars = stars the candy touched, when the level is won (0 otherwise).

What the model is told (the DeepPHY paper's information, ../shared/notes/paper-prompts.md
section 6): by default the screenshot with its labels, per element type how many there are
and their ids, the actions taken so far, what can be used now, and feedback in words; no
numbers about the world (no positions, speeds, rope lengths, distances, clock or timings).
The environment option `state_text` (an ablation) adds the numeric state: every element's
position and state, the ropes' rest lengths and pull, the candy's velocity, the clock, the
hooks' and barriers' timings, and the times of events in the feedback.
"""

from __future__ import annotations

import math

from deepphy.envs.base import (FILM_FPS, Action, EnvOptions, Environment, Frame, Observation, ObservationCache,
                               StepResult, Task)
from deepphy.envs.cuttherope import SPEC
from deepphy.envs.cuttherope import constants as C
from deepphy.envs.cuttherope.level import BOX_THEMES, Level, level_ids, load_level
from deepphy.envs.cuttherope.render import render
from deepphy.envs.cuttherope.sim import World, seconds_to_steps
from deepphy.envs.cuttherope.space import MULTI_CUTS, CutAction, CutSpace
from deepphy.envs.images import Image


INITIAL = ObservationCache()


class CutTheRopeOptions(EnvOptions):
    """Cut the Rope's options: the shared ones only. `state_text` here adds every element's
    position, rope lengths, speeds and the world's clock (see the module's docstring)."""


class Attempt:
    """One attempt's rules, without pictures: the world, the actions taken, the cushions
    tapped. The environment plays through it; so does the calibration's reference baseline.
    `clock`: the feedback gives the world's time of each event (the state_text option)."""

    def __init__(self, level: Level, clock: bool = False) -> None:
        self.world = World.from_level(level)
        self.clock = clock
        self.actions = 0
        self.history: list[str] = []  # the actions taken, in the syntax
        self.tapped: list[int] = []
        self.done = False
        self.truncated = False

    def space(self) -> CutSpace:
        world = self.world
        avail = world.available()
        level = world.level
        return CutSpace(num_pins=len(level.pins), num_active_pins=len(level.active_pins),
                        num_bubbles=len(level.bubbles), num_cushions=len(level.cushions),
                        pins=avail["pins"], active_pins=avail["active_pins"], bubbles=avail["bubbles"],
                        cushions_tapped=sorted(self.tapped))

    def play(self, action: CutAction) -> list[str]:
        """Apply one valid action and let the world run; after the last action it runs on
        to decide. Returns the feedback, in parts."""
        assert not self.done, "the attempt is over"
        world = self.world
        self.actions += 1
        if action.name == "tap_air_cushion" and action.ids[0] not in self.tapped:
            self.tapped.append(action.ids[0])
        self.history.append(format_action(action))
        words = act(world, action)
        feedback = [f"{format_action(action)}: {words}", *_event_words(world, self.clock)]
        if not world.decided and self.actions >= C.MAX_ACTIONS:
            feedback.append(f"that was the last of {C.MAX_ACTIONS} actions: the world runs on "
                            f"(at most {C.RUN_ON_CAP:g} s) to decide the outcome")
            world.run_on(seconds_to_steps(C.RUN_ON_CAP))
            feedback += _event_words(world, self.clock)
            self.truncated = not world.decided
        self.done = world.decided or self.truncated
        when = f" at t = {world.time:.2f} s" if self.clock else ""
        if world.decided:
            won = world.status == "won"
            feedback.append(f"LEVEL {'WON' if won else 'LOST'}{when}: {world.reason}"
                            + (f", with {world.stars_collected} of {len(world.level.stars)} stars" if won else ""))
        elif self.truncated:
            feedback.append(f"undecided after {C.RUN_ON_CAP:g} s more: the attempt ends unsolved")
        elif self.clock:
            feedback.append(f"t = {world.time:.2f} s, stars {world.stars_collected}/{len(world.level.stars)}")
        else:
            feedback.append(f"stars {world.stars_collected}/{len(world.level.stars)}; the world is paused")
        return feedback

    @property
    def stars(self) -> int:
        """The attempt's stars: those the candy touched, if won."""
        return self.world.stars_collected if self.world.status == "won" else 0


class CutTheRopeEnv(Environment):
    spec = SPEC
    Options = CutTheRopeOptions

    def __init__(self, options: CutTheRopeOptions | None = None) -> None:
        super().__init__(options)
        self.attempt: Attempt | None = None

    @property
    def state_text(self) -> bool:
        return self.options.state_text  # type: ignore[attr-defined]

    @property
    def world(self) -> World | None:
        return self.attempt.world if self.attempt else None

    @classmethod
    def tasks(cls, options) -> list[Task]:
        return [Task(env=SPEC.name, id=i, group=i.split("_")[0], params={"level": i, "state_text": options.state_text})
                for i in level_ids()]

    # -- the contract ------------------------------------------------------------------------

    def reset(self, task: Task) -> Observation:
        level = load_level(task.params.get("level", task.id))
        key = (task.id, self.state_text)
        known = INITIAL.get(key)
        if known is not None:  # every attempt starts from the same scene: render it once
            self.start(level, observe=False)
            return known
        return INITIAL.put(key, self.start(level))

    def start(self, level: Level, observe: bool = True) -> Observation | None:
        """Start an attempt of `level` (a level given as data, e.g. one being designed)."""
        self.attempt = Attempt(level, clock=self.state_text)
        return self.observation() if observe else None

    def step(self, action: Action) -> StepResult:
        attempt = self.attempt
        assert attempt is not None and not attempt.done, "reset() first; the attempt is over"
        assert isinstance(action, CutAction)
        world = attempt.world
        problem = invalid_reason(world, action)
        if problem:
            attempt.done = True
            return StepResult(terminated=True, invalid_reason=problem, feedback=f"invalid action: {problem}",
                              stars=0, info=self._info())
        text = "; ".join(attempt.play(action))
        won = world.status == "won"
        banner = None
        if world.decided:
            banner = f"WON: {world.stars_collected} star(s)" if won else f"LOST: {world.reason}"
        elif attempt.truncated:
            banner = "not decided: out of actions"
        when = f", t = {world.time:.2f} s" if self.state_text else ""
        frame = Image.from_array(
            f"a{attempt.actions}",
            f"the level after action {attempt.actions} ({format_action(action)}){when}; "
            "magenta dots trace the candy's path",
            render(world, trail=True, banner=banner[:60] if banner else None, clock=self.state_text),
        )
        return StepResult(
            terminated=world.decided,
            truncated=attempt.truncated,
            success=won,
            observation=None if attempt.done else self.observation(),
            feedback=text,
            key_frames=[frame],
            stars=attempt.stars if attempt.done else None,
            info=self._info(),
        )

    def film(self, action: Action) -> tuple[StepResult, list[Frame]]:
        """`step`, with a picture of the world FILM_FPS times per simulated second while it
        runs (the world is only looked at: a copy is drawn)."""
        world = self.world
        pictures: list[Frame] = []

        def watch(now: World) -> None:
            if now.step_count * FILM_FPS // C.STEPS_PER_SECOND > (now.step_count - 1) * FILM_FPS // C.STEPS_PER_SECOND:
                view = now.snapshot()
                view.watch = None
                view.place_attachments()
                pictures.append(Frame(render(view), f"t = {now.time:.2f} s"))

        world.watch = watch
        try:
            result = self.step(action)
        finally:
            world.watch = None
        return result, pictures

    # -- observation --------------------------------------------------------------------------

    def space(self) -> CutSpace:
        return self.attempt.space()

    def observation(self) -> Observation:
        world = self.world
        now = f"at t = {world.time:.2f} s" if self.state_text else "now (the world is paused)"
        image = Image.from_array(
            "scene",
            f"The level {now}. Yellow labels name what actions can use (P pins, A active pins, "
            "B bubbles, C air cushions); white labels name magic hats (H) and electric barriers (E).",
            render(world, clock=self.state_text),
        )
        text = (describe_state(world, self.attempt.actions) if self.state_text
                else describe(world, self.attempt.history))
        return Observation(images=[image], text=text, action_space=self.space())

    def _info(self) -> dict:
        w = self.world
        return {"t": round(w.time, 2), "actions": self.attempt.actions, "status": w.status, "reason": w.reason,
                "stars_touched": w.stars_collected}


# -- shared with the oracle ---------------------------------------------------------------------------


def invalid_reason(world: World, action: CutAction) -> str | None:
    """Why `action` cannot be taken now (None if it can): the parser already checks this
    for text; this guards actions built in code."""
    avail = world.available()
    field = {"cut_pin": "pins", "cut_active_pin": "active_pins", "pop_bubble": "bubbles",
             "tap_air_cushion": "cushions"}.get(action.name)
    if field and (not action.ids or any(i not in avail[field] for i in action.ids)):
        return f"{format_action(action)}: no such element can be used now"
    if len(set(action.ids)) != len(action.ids) or (len(action.ids) > 1 and action.name not in MULTI_CUTS):
        return f"{format_action(action)}: only cuts may name several elements, each once"
    if action.name == "tap_air_cushion" and action.times not in C.TAP_TIMES:
        return f"times must be one of {C.TAP_TIMES}"
    if action.name == "sleep" and not (action.seconds is not None and C.SLEEP_MIN <= action.seconds <= C.SLEEP_MAX):
        return f"sleep must be within [{C.SLEEP_MIN:g}, {C.SLEEP_MAX:g}] s"
    return None


def act(world: World, action: CutAction) -> str:
    """The rules of one (valid) action: apply it, then let the world run (ACTION_INTERVAL,
    the sleep's seconds, or after success() and fail() until decided, at most RUN_ON_CAP).
    Returns what the action did, in words; `world.events` holds what happened while the
    world ran."""
    if action.name in ("success", "fail"):
        world.run_on(seconds_to_steps(C.RUN_ON_CAP))
        if not world.decided:
            world.status = "lost"
            world.reason = (f"success() was claimed, but Om Nom had not eaten the candy {C.RUN_ON_CAP:g} s later"
                            if action.name == "success" else
                            f"you stopped with fail(), and Om Nom had not eaten the candy {C.RUN_ON_CAP:g} s later")
        said = "declared the level won" if action.name == "success" else "stopped acting (fail)"
        return f"you {said}: the world runs on (at most {C.RUN_ON_CAP:g} s) and the game decides"
    if action.name == "sleep":
        words = f"the world runs for {action.seconds:g} s"
    else:
        words = apply(world, action)
    world.advance(seconds_to_steps(action.seconds if action.name == "sleep" else C.ACTION_INTERVAL))
    return words


def apply(world: World, action: CutAction) -> str:
    """What an element action does at the moment it is taken (the world does not run)."""
    if action.name == "cut_pin":
        return "; ".join(world.cut_pin(i) for i in action.ids)
    if action.name == "cut_active_pin":
        return "; ".join(world.cut_active_pin(i) for i in action.ids)
    if action.name == "pop_bubble":
        return world.pop_bubble(action.ids[0])
    assert action.name == "tap_air_cushion", action
    return world.tap_air_cushion(action.ids[0], action.times)


def format_action(action: CutAction) -> str:
    return CutSpace().format(action)


def _event_words(world: World, clock: bool) -> list[str]:
    """What happened while the world ran: with `clock`, each event's time; without, in order."""
    if clock:
        return [f"at t = {e.step / C.STEPS_PER_SECOND:.2f} s {e.text}" for e in world.events]
    return [f"then {e.text}" for e in world.events]


def compass(angle: float) -> str:
    names = ["right", "up-right", "up", "up-left", "left", "down-left", "down", "down-right"]
    return names[int(round((angle % 360) / 45)) % 8]


def _xy(p) -> str:
    return f"({int(round(p[0]))}, {int(round(p[1]))})"


def describe(world: World, history: list[str]) -> str:
    """The text that goes with the screenshot (the paper's information): the level and its
    box, the decision's number, per element type how many there are and their ids, the
    actions taken so far, what can be used now. Nothing the picture shows in numbers."""
    level: Level = world.level
    lines = [f"Level {level.id} (box {level.box}: {BOX_THEMES[level.box]}). "
             f"Decision {len(history) + 1} of at most {C.MAX_ACTIONS}; the world is paused."]
    kinds = []
    for noun, letter, count in (("pins", "P", len(level.pins)), ("active pins", "A", len(level.active_pins)),
                                ("bubbles", "B", len(level.bubbles)), ("air cushions", "C", len(level.cushions))):
        if count:
            kinds.append(f"{count} {noun if count > 1 else noun[:-1]} ({', '.join(f'{letter}{k}' for k in range(1, count + 1))})")
    lines.append("Elements you can act on: " + ("; ".join(kinds) if kinds else "none") + ".")
    other = []
    hooks = [f"P{k}" for k, p in enumerate(level.pins, 1) if p.track]
    if hooks:
        other.append(f"{len(hooks)} of the pins {'is a hook' if len(hooks) == 1 else 'are hooks'} on a track "
                     f"({', '.join(hooks)})")
    spiders = [f"P{s.pin}" for s in world.spiders if not s.gone]
    if spiders:
        other.append(f"{len(spiders)} spider{'s' if len(spiders) > 1 else ''} (on the rope of {', '.join(spiders)})")
    if level.hats:
        other.append(f"{len(level.hats)} pair{'s' if len(level.hats) > 1 else ''} of magic hats "
                     f"({', '.join(f'H{k}' for k in range(1, len(level.hats) + 1))})")
    if level.electrics:
        other.append(f"{len(level.electrics)} electric barrier{'s' if len(level.electrics) > 1 else ''} "
                     f"({', '.join(f'E{k}' for k in range(1, len(level.electrics) + 1))})")
    if level.spikes:
        other.append(f"{len(level.spikes)} row{'s' if len(level.spikes) > 1 else ''} of spikes")
    if level.walls:
        other.append(f"{len(level.walls)} wall{'s' if len(level.walls) > 1 else ''}")
    if level.halves:
        other.append("two candy halves to join" if not any(c.alive and not c.half for c in world.candies)
                     else "the halves have joined into one candy")
    if other:
        lines.append("Also in the level: " + "; ".join(other) + ".")
    lines.append(f"Stars collected: {world.stars_collected} of {len(level.stars)}.")
    lines.append("Your actions so far: " + ("; ".join(history) if history else "none") + ".")
    lines.append(_menu(world))
    return "\n".join(lines)


def _menu(world: World) -> str:
    avail = world.available()
    acts = ([f"cut_pin({i})" for i in avail["pins"]] + [f"cut_active_pin({i})" for i in avail["active_pins"]]
            + [f"pop_bubble({i})" for i in avail["bubbles"]]
            + [f"tap_air_cushion({i}, times=1|3|5)" for i in avail["cushions"]])
    return ("You can now: " + ", ".join(acts + [f"sleep({C.SLEEP_MIN:g}..{C.SLEEP_MAX:g})", "success()", "fail()"])
            + ".")


def describe_state(world: World, actions_taken: int) -> str:
    """The text state with the numbers (the state_text option): every element's position
    and state, the candy's velocity, the ropes' rest lengths and pull, the clock."""
    level: Level = world.level
    lines = [f"Level {level.id} (box {level.box}: {BOX_THEMES[level.box]}). Time t = {world.time:.2f} s. "
             f"Action {actions_taken + 1} of at most {C.MAX_ACTIONS}."]
    carried = {b.candy: k for k, b in enumerate(world.bubbles, 1) if b.candy is not None and not b.popped}
    candies = [(i, c) for i, c in enumerate(world.candies) if c.alive]
    for n, (i, c) in enumerate(candies, 1):
        name = f"Candy half {n}" if c.half else "Candy"
        ropes = []
        for r in world.ropes:
            if r.candy != i:
                continue
            label = f"P{r.sid}" if r.source == "pin" else f"A{r.sid}"
            stretch = world.rope_stretch(r)
            if stretch > 0.0:
                state = f"taut, stretched {stretch:.1f} px, pulling {world.rope_tension(r):.1f} candy weights"
            else:
                state = f"slack by {-stretch:.1f} px, pulling nothing"
            ropes.append(f"{label} (rest length {r.length:.0f}, {state})")
        held = "held by the ropes of " + ", ".join(ropes) if ropes else "held by no rope"
        bubble = f"; inside bubble B{carried[i]}" if i in carried else ""
        lines.append(f"{name}: at {_xy((c.x, c.y))}, velocity {_xy((c.vx, c.vy))} px/s; {held}{bubble}.")
    whole = [c for _, c in candies if not c.half]
    mouth = f"Om Nom: centre {_xy(level.om_nom)}, radius {C.OMNOM_RADIUS:g} px"
    if whole:
        gap = math.dist(level.om_nom, (whole[0].x, whole[0].y)) - C.OMNOM_RADIUS - whole[0].radius
        mouth += f"; the candy's edge is {gap:.0f} px from his"
    if level.halves and not whole:
        mouth += " (he eats only a whole candy: join the two halves first)"
    lines.append(mouth + ".")
    left = [_xy(s) for k, s in enumerate(level.stars) if not world.stars[k]]
    lines.append(f"Stars: {world.stars_collected} of {len(level.stars)} collected"
                 + (f"; still to collect at {', '.join(left)}." if left else "."))
    if level.pins:
        parts = []
        for k, p in enumerate(level.pins, 1):
            r = world.rope_of_pin(k)
            where = _xy(p.at(world.time))
            if p.track:
                vx, vy = p.velocity(world.time)
                heading = f"moving toward {_xy(p.track.to if vx * (p.track.to[0] - p.pos[0]) + vy * (p.track.to[1] - p.pos[1]) > 0 else p.pos)}"
                where += (f" (a hook sliding between {_xy(p.pos)} and {_xy(p.track.to)}, one round trip every "
                          f"{p.track.period:g} s; {heading} at {math.hypot(vx, vy):.0f} px/s)")
            parts.append(f"P{k} {where} " + (f"rope attached (rest length {r.length:.0f})" if r else "no rope (cut)"))
        lines.append("Pins: " + "; ".join(parts) + ".")
    if world.active_pins:
        words = {"armed": "waiting for the candy", "attached": "its rope holds the candy", "cut": "used (rope cut)",
                 "removed": "removed"}
        lines.append("Active pins: " + "; ".join(f"A{k} {_xy((a.x, a.y))} radius {a.radius:.0f}: {words[a.state]}"
                                                 for k, a in enumerate(world.active_pins, 1)) + ".")
    if world.bubbles:
        parts = []
        for k, b in enumerate(world.bubbles, 1):
            if b.popped:
                parts.append(f"B{k} popped")
            else:
                parts.append(f"B{k} at {_xy((b.x, b.y))} " + ("carrying the candy" if b.candy is not None else "empty"))
        lines.append("Bubbles: " + "; ".join(parts) + ".")
    if level.cushions:
        lines.append("Air cushions: " + "; ".join(f"C{k} at {_xy(c.pos)} puffing {compass(c.angle)} ({c.angle:g} deg)"
                                                  for k, c in enumerate(level.cushions, 1)) + ".")
    if level.hats:
        lines.append("Magic hats: " + "; ".join(
            f"pair H{k}: opening at {_xy(p.hats[0].pos)} facing {compass(p.hats[0].angle)} and at "
            f"{_xy(p.hats[1].pos)} facing {compass(p.hats[1].angle)}" for k, p in enumerate(level.hats, 1)) + ".")
    if level.walls:
        lines.append("Walls: " + "; ".join(f"from {_xy(w.a)} to {_xy(w.b)}" for w in level.walls) + ".")
    if level.spikes:
        lines.append("Spikes: " + "; ".join(f"from {_xy(s.a)} to {_xy(s.b)}" for s in level.spikes) + ".")
    if level.electrics:
        parts = []
        for k, e in enumerate(level.electrics):
            live = world.electric_live(k)
            into = (world.time + e.phase) % e.period
            switch = (e.on - into) if live else (e.period - into)
            parts.append(f"E{k + 1} from {_xy(e.a)} to {_xy(e.b)}: {'LIVE' if live else 'off'} now, switches in "
                         f"{switch:.2f} s (live {e.on:g} s of every {e.period:g} s)")
        lines.append("Electric barriers: " + "; ".join(parts) + ".")
    spiders = [s for s in world.spiders if not s.gone]
    if spiders:
        parts = []
        for s in spiders:
            waiting = world.time < s.delay
            rope = world.rope_of_pin(s.pin)
            left = (rope.length - s.crawled) / C.SPIDER_SPEED if rope else 0.0
            parts.append(f"on the rope of P{s.pin}, {100 * world.spider_position(s):.0f}% of the way to the candy"
                         + (f" (starts in {s.delay - world.time:.2f} s)" if waiting else
                            f" (reaches it in {left:.1f} s unless that rope is cut)"))
        lines.append("Spiders: " + "; ".join(parts) + ".")
    lines.append(_menu(world))
    return "\n".join(lines)
