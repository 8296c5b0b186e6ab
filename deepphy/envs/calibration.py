"""What both of our games' calibrations hold a level to (Angry Birds and Cut the Rope:
`deepphy solve --env <game> calibrate`); each game's own targets are in its solve.py."""

# A level the reference random baseline wins a third of the time or more measures luck, not
# understanding (DEVELOPERS.md).
RANDOM_WINS_MAX = 1 / 3


def is_opener(level_id: str) -> bool:
    """A scene's (Angry Birds) or a box's (Cut the Rope) first level: it may be as forgiving
    as the real game's openers are."""
    return level_id.endswith("_l01")


def wins_by_luck(level_id: str, random_rate: float) -> bool:
    """Random wins this level too often for it to measure anything (openers aside). The
    tolerance: exact rates are fractions (1/3 of the orders) computed in floating point."""
    return random_rate >= RANDOM_WINS_MAX - 1e-9 and not is_opener(level_id)
