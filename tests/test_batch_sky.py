"""A batch run's sky when none is given: the scene's own, as `driftframe record` takes it (the starfield
everywhere, the rotation demo's green line cube), and a given sky is kept."""
from pathlib import Path

import pytest

from driftframe.batch import Spec, SpecError, check_all
from driftframe.batch_file import load


@pytest.mark.parametrize("demo, sky", [("cradle", "starfield"), ("orbit", "starfield"), ("asteroids", "starfield"),
                                       ("rotation", "lines")])
def test_a_demo_without_a_sky_gets_its_own(demo, sky, tmp_path):
    spec = Spec(demo=demo, output=str(tmp_path / "a.mp4")).check()
    assert spec.sky == sky


def test_a_scene_without_a_sky_gets_the_starfield_and_a_given_sky_is_kept(tmp_path):
    assert Spec(scene="batch_scenes:box", seconds=0.25, output=str(tmp_path / "a.mp4")).check().sky == "starfield"
    assert Spec(demo="cradle", sky="lines", output=str(tmp_path / "b.mp4")).check().sky == "lines"
    assert Spec(demo="rotation", sky="starfield", output=str(tmp_path / "c.mp4")).check().sky == "starfield"
    with pytest.raises(SpecError, match="sky must be one of lines, starfield, got 'clouds'"):
        Spec(demo="cradle", sky="clouds").check()


def test_a_batch_file_without_a_sky_records_the_starfield(tmp_path: Path):
    f = tmp_path / "grid.toml"
    f.write_text('demo = ["cradle", "rotation"]\noutput = "{demo}-{sky}.mp4"\nseconds = 0.5\n')
    (tmp_path / "out").mkdir()
    specs = load(f, tmp_path / "out")
    assert [(s.demo, s.sky) for s in specs] == [("cradle", "starfield"), ("rotation", "lines")]
    assert [Path(s.output).name for s in specs] == ["cradle-starfield.mp4", "rotation-lines.mp4"]
    # the grid builds each run with its sky filled in: checking it keeps the very run (10^6 runs, no copies)
    unchecked = load(f, tmp_path / "out", check=False)
    assert [s.sky for s in unchecked] == ["starfield", "lines"]
    assert all(a is b for a, b in zip(check_all(unchecked), unchecked))
