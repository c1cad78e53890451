"""The legs `robot new` finds in a model (`new`): the floating base (the body with the free
joint, else the root body), the leaf bodies below it whose chain has at least two hinges and
whose foot is near the ground (all of them where the model's pose holds alike chains up or
flat: `ALIKE_COUNT`), ordered front to back and left before right and named by their
bodies' names; the gait for their count, a design parameter per leg segment kind (the two
longest links nearest each foot), the joints several legs share and the actuated hinges.
"""

from __future__ import annotations

import re

import mujoco
import numpy as np

from coadapt_core.errors import UserError

#: a leaf body is a foot when it lies this share of the base's height above the lowest leaf
#: at most (a humanoid's hands are not)
FOOT_BAND = 0.25
#: a link counts as a leg segment when at least this share of its chain's longest link
SEGMENT_SHARE = 0.25
#: legs posed up or flat at the model's pose (no foot FOOT_BAND of the chains' mean length
#: below the base, or fewer than two near the ground) are taken as they are when the chains
#: are alike: ALIKE_COUNT or more, one hinge count, lengths within ALIKE_SHARE of the longest
#: (PyBullet's microtaur, its legs straight out sideways at 0; its environment poses them)
ALIKE_COUNT = 4
ALIKE_SHARE = 0.1


def _base(model: mujoco.MjModel) -> int:
    for j in range(model.njnt):
        if model.jnt_type[j] == mujoco.mjtJoint.mjJNT_FREE:
            return int(model.jnt_bodyid[j])
    roots = [b for b in range(1, model.nbody) if model.body_parentid[b] == 0]
    if len(roots) != 1:
        raise UserError(f"the model has {len(roots)} root bodies and no free joint", field="model")
    return roots[0]


def _chain(model: mujoco.MjModel, base: int, leaf: int) -> list[int]:
    path, b = [], leaf
    while b != base and b != 0:
        path.append(b)
        b = int(model.body_parentid[b])
    return list(reversed(path)) if b == base else []


def _hinges(model: mujoco.MjModel, bodies: list[int]) -> int:
    return sum(
        1
        for j in range(model.njnt)
        if model.jnt_bodyid[j] in bodies and model.jnt_type[j] == mujoco.mjtJoint.mjJNT_HINGE
    )


def _common_kind(names: list[str]) -> str:
    """What the legs' body names share once their side or leg tokens are dropped: the longest
    common run of trailing tokens ("FL_thigh", "RR_thigh" -> "thigh"; "ml_femur_link",
    "fr_femur_link" -> "femur"), else of leading ones, else ""."""
    split = [[t for t in re.split(r"[_\-.]+", n.lower()) if t] for n in names]
    for tokens in split:
        while tokens and tokens[-1] in ("link", "body"):
            tokens.pop()
    tail = []
    for group in zip(*(reversed(t) for t in split), strict=False):
        if len(set(group)) != 1:
            break
        tail.insert(0, group[0])
    if not tail:
        for group in zip(*split, strict=False):
            if len(set(group)) != 1:
                break
            tail.append(group[0])
    kind = "_".join(tail)
    return re.sub(r"[^a-z0-9_]+", "_", kind).strip("_")


def _gait(count: int) -> list[float]:
    if count == 2:
        return [0.0, 0.5]
    if count == 4:  # trot: the diagonal pairs together (legs ordered front left, front right, ...)
        return [0.0, 0.5, 0.5, 0.0]
    if count == 6:  # tripod: front and hind of one side with the middle of the other
        return [0.0, 0.5, 0.5, 0.0, 0.0, 0.5]
    return [round(k / count, 6) for k in range(count)]


def _legs(model, data, base: int, band: bool = True, skip: frozenset = frozenset()) -> list[dict]:
    """The legs at `data`'s pose (module docstring); `band` False keeps every chain (a
    four-bar's halves point up at the model's zero pose: none is near the ground there);
    the bodies named in `skip` (a four-bar's pin bodies) are no feet."""
    leaves = [
        b
        for b in range(1, model.nbody)
        if not any(model.body_parentid[c] == b for c in range(1, model.nbody))
        and model.body(b).name not in skip
    ]
    legs = []
    for leaf in leaves:
        chain = _chain(model, base, leaf)
        if len(chain) >= 2 and _hinges(model, chain) >= 2:
            legs.append({"foot": leaf, "chain": chain, "pos": data.xpos[leaf].copy()})
    if not legs:
        raise UserError(
            "found no legs: no leaf body below the base ends a chain of two or more hinges",
            field="model",
        )
    # feet near the ground: a leaf well above the lowest foot is an arm or a tail
    if not band:
        legs.sort(key=lambda g: (-round(float(g["pos"][0]), 2), -float(g["pos"][1])))
        return legs
    lowest = min(float(g["pos"][2]) for g in legs)
    reach = float(data.xpos[base][2]) - lowest
    lengths = [_length(model, g["chain"]) for g in legs]
    if reach < FOOT_BAND * float(np.mean(lengths)) and _alike(model, legs, lengths):
        return _posed_up(legs)
    reach = max(reach, 1e-9)
    kept = [g for g in legs if float(g["pos"][2]) <= lowest + FOOT_BAND * reach]
    if len(kept) < 2 <= len(legs) and _alike(model, legs, lengths):
        return _posed_up(legs)
    if len(kept) < 2 <= len(legs):
        raised = [model.body(g["foot"]).name for g in legs if g not in kept]
        raise UserError(
            f"found one leg standing: at the model's pose (its keyframe, else each joint at 0 "
            f"or its nearest limit) the chains ending in {', '.join(raised)} end above the "
            f"lowest foot by more than {FOOT_BAND:g} of the base's height over it (arms, or "
            "legs posed upward); robot new needs two feet near the ground there",
            field="model",
        )
    legs = kept
    # front to back (x rounded to a centimetre), then left (y > 0) before right
    legs.sort(key=lambda g: (-round(float(g["pos"][0]), 2), -float(g["pos"][1])))
    return legs


def _length(model: mujoco.MjModel, chain: list[int]) -> float:
    """A chain's length: its bodies' offsets from their parents summed."""
    return float(sum(np.linalg.norm(model.body_pos[b]) for b in chain))


def _alike(model: mujoco.MjModel, legs: list[dict], lengths: list[float]) -> bool:
    """Whether the chains are alike enough to be taken as the legs as they are posed (at
    least ALIKE_COUNT, one hinge count, lengths within ALIKE_SHARE of the longest)."""
    hinges = {_hinges(model, g["chain"]) for g in legs}
    longest = max(lengths)
    return (
        len(legs) >= ALIKE_COUNT
        and len(hinges) == 1
        and longest - min(lengths) <= ALIKE_SHARE * longest
    )


def _posed_up(legs: list[dict]) -> list[dict]:
    """The legs posed up or flat (`ALIKE_COUNT`), each marked `raised` (the standing solve
    then puts a foot the pose holds out sideways beyond reach under its hip,
    `stand.OUT_SHARE`), in leg order."""
    for g in legs:
        g["raised"] = True
    legs.sort(key=lambda g: (-round(float(g["pos"][0]), 2), -float(g["pos"][1])))
    return legs


def _segments(model, legs: list[dict], share: float = SEGMENT_SHARE) -> list[dict]:
    """Up to two parameters (upper, lower leg) from the longest links nearest the feet (at
    least `share` of the chain's longest: 0 takes the last two links, a four-bar's halves')."""
    per_leg = []
    for leg in legs:
        links = [(model.body_parentid[b], b) for b in leg["chain"][1:]]
        lengths = [float(np.linalg.norm(model.body_pos[c])) for _, c in links]
        longest = max(lengths, default=0.0)
        kept = [
            link for link, length in zip(links, lengths, strict=True) if length >= share * longest
        ]
        per_leg.append(kept[-2:])
    count = min(len(k) for k in per_leg)
    params = []
    for k in range(count):
        links = [kept[len(kept) - count + k] for kept in per_leg]
        kind = _common_kind([model.body(int(p)).name for p, _ in links])
        name = (kind or ("upper_leg", "lower_leg")[k % 2]) + "_scale"
        length = float(np.linalg.norm(model.body_pos[links[0][1]]))
        params.append(
            {
                "name": name,
                "bounds": [0.7, 1.3],
                "nominal": 1.0,
                "unit": f"x {length:.3g} m",
                "links": [[model.body(int(p)).name, model.body(int(c)).name] for p, c in links],
                "mass": "stretch",
                "stretch_share": 1.0,
            }
        )
    return params


def _shared_joints(model: mujoco.MjModel, legs: list[dict]) -> list[str]:
    """The hinge joints on the chains of two legs or more (a humanoid's abdomen), in model
    order."""
    count: dict[int, int] = {}
    for g in legs:
        for j in range(model.njnt):
            if (
                model.jnt_bodyid[j] in g["chain"]
                and model.jnt_type[j] == mujoco.mjtJoint.mjJNT_HINGE
            ):
                count[j] = count.get(j, 0) + 1
    return [model.joint(j).name for j in sorted(count) if count[j] > 1]


def _actuated(model: mujoco.MjModel, base: int) -> list[str]:
    """The hinge joints of the base's subtree, in model order (as `model.prepare` lists them)."""
    out = []
    for j in range(model.njnt):
        if model.jnt_type[j] != mujoco.mjtJoint.mjJNT_HINGE:
            continue
        b = int(model.jnt_bodyid[j])
        while b not in (base, 0):
            b = int(model.body_parentid[b])
        if b == base:
            out.append(model.joint(j).name)
    return out


_SIDE_TOKENS = re.compile(
    r"^(fl|fr|rl|rr|hl|hr|lf|rf|lh|rh|ml|mr|l|r|left|right|front|back|rear|hind|fore|middle|mid"
    r"|[0-9]+)$"
)


def _tokens(name: str) -> list[str]:
    spaced = re.sub(r"([a-z0-9])([A-Z])|([A-Za-z])([0-9])", r"\1\3_\2\4", name)
    return [t for t in re.split(r"[_\-.\s]+", spaced) if t]


def _leg_names(model: mujoco.MjModel, legs: list[dict]) -> list[str]:
    """Each leg's name from its bodies' names: the tokens that tell its foot's name from the
    other feet's (FL_toe -> FL, left_foot -> left, front_left_foot -> front_left), else from
    the next body up its chain; by position when no body tells them apart."""
    for depth in range(max(len(g["chain"]) for g in legs)):
        names = [model.body(g["chain"][max(len(g["chain"]) - 1 - depth, 0)]).name for g in legs]
        split = [_tokens(n) for n in names]
        common = set.intersection(*(set(t.lower() for t in ts) for ts in split))
        found = []
        for ts in split:
            own = [t for t in ts if t.lower() not in common]
            sides = [t for t in own if _SIDE_TOKENS.match(t.lower())]
            found.append("_".join(sides or own))
        if all(found) and len(set(f.lower() for f in found)) == len(found):
            if not all(f.isdigit() for f in found):  # numbers say less than positions
                return found
            break
    if len(legs) == 2:
        return ["left", "right"]
    if len(legs) == 4:
        return ["FL", "FR", "RL", "RR"]
    return [f"leg{k}" for k in range(len(legs))]
