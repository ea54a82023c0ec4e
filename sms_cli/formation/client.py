"""The client spacecraft of a mission's ``client:`` section, compiled as its own SystemModel by the same
compiler as the servicer, with every error located in the mission file under ``client.``."""

from __future__ import annotations

from dataclasses import dataclass

from sms_cli.mission.load import LoadedMission
from sms_cli.mission.yaml_source import SourceMap


@dataclass
class _ClientSource(SourceMap):
    """The mission's source map seen from the ``client:`` section: a key path ``robot.urdf`` of the client
    is looked up as ``client.robot.urdf``."""

    outer: SourceMap | None = None

    def _key(self, path) -> tuple:
        return ("client", *tuple(path))

    def file_of(self, path):
        return self.outer.file_of(self._key(path))

    def locate(self, path, prefer_key: bool = False):
        return self.outer.locate(self._key(path), prefer_key)


def client_view(loaded: LoadedMission) -> LoadedMission:
    """A mission holding only the client's robot, wheels and thrusters (for ``compile_system``), whose errors and
    relative paths refer to the ``client:`` section of ``loaded``."""
    from sms_cli.mission.schema import Mission

    c = loaded.mission.client
    mission = Mission(name=f"{loaded.mission.name}.{c.name}", robot=c.robot, wheels=c.wheels, thrusters=c.thrusters)
    source = _ClientSource(file=loaded.source.file, text=loaded.source.text, outer=loaded.source)
    return LoadedMission(mission, loaded.path, source, loaded.text)


def initial_poses(mission, servicer) -> tuple:
    """(servicer base, client base) world poses at t = 0 (``pinocchio.SE3``): the servicer's from its compiled
    initial state, the client's ``client.pose`` in the servicer's base frame."""
    import pinocchio as pin

    g_servicer = pin.XYZQUATToSE3(servicer.q0[:7])
    return g_servicer, g_servicer * mission.client.pose.se3()


def compile_client(loaded: LoadedMission, strict: bool = False):
    """The client's SystemModel (InputError, exit 2, located under ``client.`` on any problem)."""
    from sms_cli.model.compiler import compile_system

    return compile_system(client_view(loaded), strict=strict)
