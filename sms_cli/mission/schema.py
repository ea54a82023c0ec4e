"""The mission file: one YAML document, one ``Mission``. Each stage owns its section."""

from __future__ import annotations

from pydantic import Field, model_validator

from sms_cli.mission.base import StrictModel, unique
from sms_cli.mission.system import (
    AppendageSpec,
    InitialState,
    PayloadSpec,
    RobotSpec,
    SpringSpec,
    WheelsSpec,
)
from sms_cli.analysis.schema import AnalysisSpec
from sms_cli.campaign.schema import CampaignSpec
from sms_cli.check.schema import RequirementSpec
from sms_cli.formation.schema import SERVICER, ClientSpec, FormationSpec
from sms_cli.orbit.schema import BudgetSpec
from sms_cli.sim.schema import SimulationSpec
from sms_cli.synthesis.schema import SynthesisSpec
from sms_cli.thrusters.schema import ThrustersSpec


class Mission(StrictModel):
    """A servicing mission: the robot, its spacecraft extras and the stages to run."""

    extends: str | None = Field(
        None, description="another mission file (relative path) this one starts from: mappings merge key by key, "
                          "anything else written here replaces the inherited value")
    name: str = Field(description="short mission name (used in reports)")
    description: str = Field("", description="what this mission studies; cite the source")
    robot: RobotSpec | None = Field(None, description="the URDF robot (optional for budget-only missions)")
    wheels: WheelsSpec = Field(default_factory=WheelsSpec)
    appendages: list[AppendageSpec] = Field(default_factory=list)
    springs: list[SpringSpec] = Field(default_factory=list)
    payloads: list[PayloadSpec] = Field(default_factory=list)
    initial: InitialState = Field(default_factory=InitialState)
    thrusters: ThrustersSpec | None = Field(
        None, description="the base's on/off thrusters (Vicariotto 2023 Table 3.1): a list or the 24-thruster cube, "
                          "firing cycle, minimum impulse bit, quantisation, tank; used by attitude_actuator: "
                          "thrusters and free-flying phases instead of the ideal torque source")
    budget: BudgetSpec | None = Field(
        None, description="orbital ΔV, propellant and burn-time budget (sms budget): orbit, propulsion, "
                          "spacecraft masses and a manoeuvre sequence (or several scenarios)")
    analysis: AnalysisSpec | None = Field(
        None, description="workspace sampling, kinematic indices, design variants and modal analysis (sms analyze)")
    simulation: SimulationSpec | None = Field(
        None, description="nonlinear simulation (sms simulate): steps, controllers, actuators, sensors, phases")
    requirements: list[RequirementSpec] = Field(
        default_factory=list, description="pass/fail requirements on results.json metrics (sms run, sms check): "
                                          "{name, metric: dotted path, max | min | equals (+ tol), unit, stage}")
    synthesis: SynthesisSpec | None = Field(
        None, description="controller/observer gain synthesis (sms synthesize): the LMI of Kraiem (2022), PD, LQR or SMC")
    client: ClientSpec | None = Field(
        None, description="a second spacecraft (the client, Vicariotto 2023 ch. 5): its URDF, wheels and pose in the "
                          "servicer's base frame at t = 0")
    formation: FormationSpec | None = Field(
        None, description="two-spacecraft simulation (sms simulate, instead of simulation:): locked/shape decomposition, "
                          "relative laws, pushes (Vicariotto 2023 §5.3-5.4); needs client:")
    campaign: CampaignSpec | None = Field(
        None, description="Monte-Carlo dispersions or a parameter sweep of this mission (sms campaign): designs, "
                          "dispersions at dotted paths, stages, timeout, retries, campaign requirements")

    @model_validator(mode="after")
    def _unique_names(self):
        unique([p.name for p in self.payloads], "payload", "payloads", "name")
        unique([a.name for a in self.appendages], "appendage", "appendages", "name")
        unique([s.joint for s in self.springs], "spring joint", "springs", "joint")
        if self.formation is not None:
            if self.client is None:
                raise ValueError("formation: simulates two spacecraft: add a client: section (its robot and pose)")
            if self.simulation is not None:
                raise ValueError("a mission simulates one spacecraft (simulation:) or two (formation:), not both: "
                                 "move one of them to another mission file")
            names = (SERVICER, self.client.name)
            for what, name in [("formation.master", self.formation.master)] + [
                    (f"formation.pushes[{i}].body", p.body) for i, p in enumerate(self.formation.pushes)] + [
                    ("formation.initial.bodies", n) for n in self.formation.initial.bodies] + [
                    ("formation.actuation", a) for a in [self.formation.actuation] if a not in ("both", "master", "other")]:
                if name not in names:
                    raise ValueError(f"{what} is '{name}': the spacecraft are '{names[0]}' and '{names[1]}'")
        return self
