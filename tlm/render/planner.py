"""The pass planner: which frames a run renders, and why the others are left out.

The thesis renders multi-pass, RenderMan-like: a ray-cast frame with shadows, then
reflection and refraction frames, summed into the final image (Fig. 9). The modes are
cumulative: ``rcast`` < ``reflect`` < ``refract``. A pass the mode asks for is still
left out when the scene cannot use it: no mirror material, no Reflect pass; no
dielectric, no Refract pass; a depth of 0, nothing to follow. A scene without lights
renders primary visibility only (black), and the planner says so.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

from tlm.config import MODES, RunConfig
from tlm.scenes.model import Scene

PASSES = ("rcast", "reflect", "refract")


@dataclass(frozen=True)
class PassPlan:
    name: str
    run: bool
    reason: str


@dataclass(frozen=True)
class Plan:
    passes: tuple[PassPlan, ...]
    notes: tuple[str, ...]

    def runs(self, name: str) -> bool:
        return any(p.name == name and p.run for p in self.passes)

    @property
    def run_names(self) -> list[str]:
        return [p.name for p in self.passes if p.run]

    def to_dict(self) -> dict:
        return {
            "run": self.run_names,
            "left_out": {p.name: p.reason for p in self.passes if not p.run},
            "reasons": {p.name: p.reason for p in self.passes},
            "notes": list(self.notes),
        }


def plan(scene: Scene, cfg: RunConfig) -> Plan:
    """Decide the passes of ``cfg.mode`` for ``scene``."""
    wanted = set(PASSES[: MODES.index(cfg.mode) + 1])
    kinds = scene.kinds_present()
    notes = []
    if not scene.lights:
        notes.append("the scene has no lights: no shadow rays are cast and every frame is black")
    elif all(max(lt.power) == 0.0 for lt in scene.lights):
        notes.append("every light has zero power: frames are black (shadow rays are still cast)")
    if "lambertian" not in kinds:
        notes.append("the scene has no Lambertian surface: nothing receives direct light")

    def decide(name: str, needs: str | None, depth: int | None) -> PassPlan:
        if name not in wanted:
            return PassPlan(name, False, f"mode {cfg.mode!r} does not include the {name} pass")
        if needs is not None and needs not in kinds:
            return PassPlan(name, False, f"the scene has no {needs} material")
        if depth == 0:
            return PassPlan(name, False, f"render.{name}_depth is 0")
        return PassPlan(name, True, f"mode {cfg.mode!r} asks for it and the scene has what it needs")

    passes = (
        PassPlan("rcast", True, "every mode casts primary rays with shadow rays"),
        decide("reflect", "mirror", cfg.render.reflect_depth),
        decide("refract", "dielectric", cfg.render.refract_depth),
    )
    return Plan(passes, tuple(notes))


def plan_dict(p: Plan) -> dict:
    return {"passes": [asdict(x) for x in p.passes], **p.to_dict()}
