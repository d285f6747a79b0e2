"""`cartpush push --robot PROFILE.toml`: a profile file on the command line, its one-line errors, the saturation note."""

from __future__ import annotations

from cartpush.cli.app import main
from cartpush.cli.push import saturation_note
from tests.robots.profile_files import tiago_profile, write_profile


def test_push_with_a_profile_file_prints_the_saturation_note(tmp_path, capsys):
    path = tiago_profile(tmp_path)
    assert main(["push", "--robot", str(path), "--trajectory", "1", "--duration", "8", "--no-estimation"]) == 0
    out = capsys.readouterr().out
    assert "allocation never saturated" in out or "allocation saturated" in out
    assert "within the limits" in out  # the torque verdict: the allocation kept every joint within its limit


def test_a_bad_profile_is_exit_2_naming_the_key(tmp_path, capsys):
    bad = write_profile(
        tmp_path,
        f'name = "x"\nurdf = "{tiago_profile(tmp_path).parent}/none.urdf"\nbase = "differential"\n'
        'wheel_joints = ["l", "r"]\n[[arms]]\njoints = ["a"]\ngripper_frame = "g"\n',
        "bad.toml",
    )
    assert main(["push", "--robot", str(bad), "--duration", "8", "--json"]) == 2
    err = capsys.readouterr().err
    assert "--robot" in err and ": urdf: file" in err and len(err.strip().splitlines()) == 1


def test_saturation_note_names_each_binding_limit_longest_first():
    note = saturation_note(
        {
            "arm0 arm_6_joint torque limit (6.6 N m)": {
                "total_s": 0.58,
                "spans": 1,
                "longest_s": 0.58,
                "first_s": 2.43,
            },
            "arm0 arm_5_joint torque limit (3 N m)": {"total_s": 0.89, "spans": 2, "longest_s": 0.5, "first_s": 3.01},
        }
    ).splitlines()
    assert note[1].strip().startswith("arm0 arm_5_joint") and "0.89 s in 2 stretch(es), longest 0.50 s" in note[1]
    assert note[2].strip().startswith("arm0 arm_6_joint") and "from t = 2.43 s" in note[2]
