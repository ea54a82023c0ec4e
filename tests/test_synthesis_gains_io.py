"""gains.yaml round trip and validation errors."""

import pytest

from sms_cli.errors import InputError
from sms_cli.synthesis.gains_io import ControllerGains, GainsFile, ObserverGains, read_gains, write_gains


def test_round_trip(tmp_path):
    g = GainsFile(mission="m", law="lmi", variant="ndi_observer", actuators=["rw1", "j1"],
                  controller=ControllerGains(units="acceleration", kp=[1.0, 2.0], kv=[3.0, 4.0]),
                  observer=ObserverGains(states=["e", "w0_x"], outputs=["w0_x"], L=[[1.0], [2.0]]),
                  guarantee={"gamma": 0.5})
    p = write_gains(tmp_path / "gains.yaml", g)
    assert read_gains(p) == g


def test_bad_dimensions_are_input_errors(tmp_path):
    p = tmp_path / "gains.yaml"
    p.write_text("format: sms-gains/1\nmission: m\nlaw: pd\nactuators: [a, b]\n"
                 "controller: {units: torque, kp: [1.0], kv: [1.0, 2.0]}\n")
    with pytest.raises(InputError) as e:
        read_gains(p)
    assert e.value.exit_code == 2 and "one value per actuator" in e.value.render()
    p.write_text("format: sms-gains/1\nmission: m\nlaw: pid\n")
    with pytest.raises(InputError) as e:
        read_gains(p)
    assert "law" in e.value.render()
