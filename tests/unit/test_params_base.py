"""A parameter file that says only what differs from a base set, validated like a whole set."""

from __future__ import annotations

from pathlib import Path

import pytest

from drivetrain_ctrl.cli import main
from drivetrain_ctrl.plant.params import ParameterError, default_params, load_params


def _write(path: Path, text: str) -> Path:
    path.write_text(text, encoding="utf-8")
    return path


HEAVY = 'base = "passenger-car"\n\n[meta]\nname = "heavy"\n\n[vehicle]\nM_v = 1600.0\n'


def test_a_file_overrides_its_base_and_keeps_the_rest(tmp_path: Path) -> None:
    p = default_params()
    h = load_params(_write(tmp_path / "heavy.toml", HEAVY))
    assert h.name == "heavy" and h.description == p.description
    assert h.vehicle.M_v == 1600.0 and p.vehicle.M_v != 1600.0
    assert h.clutch == p.clutch and h.engine == p.engine and h.gearbox == p.gearbox
    # the base's source of the overridden value no longer describes it
    assert "vehicle.M_v" in dict(p.provenance) and "vehicle.M_v" not in dict(h.provenance)
    assert dict(h.provenance)["engine.J1"] == dict(p.provenance)["engine.J1"]


def test_a_base_can_be_a_file_relative_to_the_one_naming_it(tmp_path: Path) -> None:
    _write(tmp_path / "heavy.toml", HEAVY)
    sub = tmp_path / "variants"
    sub.mkdir()
    f = _write(
        sub / "heavy-strong.toml",
        'base = "../heavy.toml"\n\n[meta]\nname = "heavy, strong clutch"\n\n'
        '[clutch]\nk12_max = 300.0\n\n[provenance]\n"clutch.k12_max" = "test bench"\n',
    )
    q = load_params(f)
    assert q.vehicle.M_v == 1600.0 and q.clutch.k12_max == 300.0
    assert dict(q.provenance)["clutch.k12_max"] == "test bench"


@pytest.mark.parametrize(
    ("text", "msg"),
    [
        ('base = "passenger-car"\n[meta]\nname = "x"\n[vehicle]\nM_v = -1.0\n', "vehicle.M_v = -1"),
        ('base = "passenger-car"\n[meta]\nname = "x"\n[vehicle]\nMv = 1.0\n', "did you mean 'M_v'"),
        ('base = "passenger-kar"\n[meta]\nname = "x"\n', "did you mean 'passenger-car'"),
        ('base = "passenger-car"\n[vehicle]\nM_v = 1400.0\n', "needs a name of its own"),
        ('base = 3\n[meta]\nname = "x"\n', "base = 3"),
        ('base = "nowhere.toml"\n[meta]\nname = "x"\n', "no such parameter file"),
    ],
)
def test_bad_overrides_and_bases_are_named(tmp_path: Path, text: str, msg: str) -> None:
    f = _write(tmp_path / "bad.toml", text)
    with pytest.raises(ParameterError, match=msg) as info:
        load_params(f)
    assert str(f) in str(info.value)


def test_sets_that_name_each_other_are_an_error(tmp_path: Path) -> None:
    _write(tmp_path / "a.toml", 'base = "b.toml"\n[meta]\nname = "a"\n')
    _write(tmp_path / "b.toml", 'base = "a.toml"\n[meta]\nname = "b"\n')
    with pytest.raises(ParameterError, match="circle"):
        load_params(tmp_path / "a.toml")


def test_the_cli_shows_a_derived_set(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    f = _write(tmp_path / "heavy.toml", HEAVY)
    assert main(["params", "show", str(f)]) == 0
    out = capsys.readouterr().out
    assert "heavy" in out and "1600" in out
