"""Kinetix prompt: drive a level's motors and thrusters so a green shape reaches a blue one.

By default it gives what the paper's Kinetix prompt gives (docs/comparability.md): the legend,
the controls and their labels, the last 5 frames, actions and goal distances; not the level's
name (Kinetix's names hint at the solution), a decision's duration or the decisions left.
`state_text=true` adds those."""

from deepphy.envs.base import Observation, Task
from deepphy.envs.kinetix.levels import MAX_DECISIONS, SECONDS_PER_DECISION
from deepphy.prompts.base import EnvPrompt

SIZE_WORDS = {"S": "small", "M": "medium", "L": "large"}


class KinetixPrompt(EnvPrompt):
    recent_steps_shown = 5  # the last 5 frames, actions and goal distances

    def rules(self, task: Task, observation: Observation) -> str:
        space = observation.action_space
        m, t = space.num_motors, space.num_thrusters  # type: ignore[attr-defined]
        labels = space.labels()  # type: ignore[attr-defined]
        annotated = any(i.name == "annotated" for i in observation.images)
        if annotated:
            where = (
                "In the annotated image each motor carries a yellow label M0, M1, ... and each "
                "thruster a label T0, T1, ...; parts that share a label are driven together by one entry."
            )
        else:
            where = (
                "The labels of the motors and thrusters are not shown: work out from the scene which "
                "part each entry drives (several parts may share one entry)."
            )
        entries = []
        if m:
            entries.append(
                f"- {m} motor entr{'y' if m == 1 else 'ies'} ({', '.join(labels[:m])}): 0 = off (the joint turns freely), "
                "1 = drive one way, 2 = drive the other way (which way is clockwise depends on the "
                "part: watch what your decisions do);"
            )
        if t:
            entries.append(
                f"- {t} thruster entr{'y' if t == 1 else 'ies'} ({', '.join(labels[m:])}): 0 = off, 1 = fire;"
            )
        w, h = observation.images[0].size
        rich = bool(task.params.get("state_text"))  # the level's name, a decision's duration, the budget
        level = f' ("{task.id}", a {SIZE_WORDS.get(task.group, task.group)} level)' if rich else ""
        held = (f"is held for about {SECONDS_PER_DECISION:.2f} s of\nsimulated time; then you see the new scene and decide "
                f"again. You have at most {MAX_DECISIONS} decisions." if rich else
                "is held for a short while; then you see\nthe new scene and decide again.")
        return f"""You are controlling a machine in a 2D physics level of Kinetix{level}. Gravity pulls down.

What the image shows (white background):
- green shapes: the shapes that must reach the goal;
- blue shapes: the goal;
- red shapes: deadly; if a green shape touches red, the level is lost;
- gray shapes: neutral parts and obstacles (dark gray = fixed in place, light gray = free to move);
  a black line on a circle shows how far it has rotated;
- orange discs with a black cross: motors; a motor turns the joint it sits on;
- purple triangles: thrusters; when fired, a thruster pushes the shape it is attached to in the
  direction its tip points (a yellow flame shows a thruster that fired during the last decision);
- small white dots are free hinges and small black dots are rigid welds; you cannot control them.
{where}

Goal: make a green shape touch a blue shape. Touching red, or running out of time, fails.

How you act: every decision sets all controls at once and {held}
A decision is a JSON list of exactly {m + t} integer{'s' if m + t != 1 else ''}, in this order: [{', '.join(labels)}].
{chr(10).join(entries)}
After each decision you are told the goal distance: the distance in pixels between the centre of
the green shape and the centre of the nearest blue shape{f" (the image is {w}x{h} pixels)" if rich else ""}.

A reply that does not contain such a list, has the wrong number of entries, or uses a value out of
range is an invalid action and ends the attempt as a failure."""

    def prediction_hint(self) -> str:
        return "how the machine and the green shape will move during this decision, and whether the goal distance will shrink"

    def example(self, observation: Observation) -> str:
        space = observation.action_space
        m, t = space.num_motors, space.num_thrusters  # type: ignore[attr-defined]
        return str([1] * m + [1] * t)
