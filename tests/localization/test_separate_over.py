"""With no number of targets given, a box behind an occluder plate, seen from 3-4 spots, is
reported as two targets, not three: 'auto' had kept a sliver 0.2-0.8 m from either object that
it accepted before the plate that found the box's rest, and that the final fit no longer held
(model.policy.select.held_plates). Scenario draws 23 and 127 (`nlos-cl reproduce scenarios`),
as their scene files: `nlos-cl simulate`, then `nlos-cl locate --json` with no option."""
import json

import numpy as np
import pytest

from nlos_cl.apps.cli import main as cli

SCENES = {
    23: {"setup": {"detector_spots": [[0.617563, 0.0, 0.727099], [-0.956992, 0.0, 0.510864],
                                      [1.735357, 0.0, -0.91669]]},
         "targets": [{"shape": "box", "size_m": [0.3672, 0.5567, 0.6976],
                      "rotation_deg": [0, 0, -2.898], "position": [2.57874, 2.247153, 0.19795]},
                     {"shape": "rectangle", "size_m": [0.9787, 1.2027],
                      "normal": [-0.115438, -0.993315, 0.0],
                      "position": [0.47232, 1.061294, -0.157519]}],
         "facet_size_m": 0.02, "noise": {"seed": 2146885257, "snr_db": 15.168}},
    127: {"setup": {"detector_spots": [[1.757306, 0.0, 0.609916], [-0.46363, 0.0, -0.413239],
                                       [1.891515, 0.0, -0.228228], [0.086376, 0.0, 0.750823]]},
          "targets": [{"shape": "box", "size_m": [0.7895, 0.4601, 0.7318],
                       "rotation_deg": [0, 0, -19.628],
                       "position": [1.710434, 2.284012, -0.443791]},
                      {"shape": "rectangle", "size_m": [1.0229, 0.4585],
                       "normal": [-0.52272, -0.852505, 0.0],
                       "position": [1.489882, 1.362731, -0.148161]}],
          "facet_size_m": 0.02, "noise": {"seed": 1210365048, "snr_db": 15.887}},
}


@pytest.mark.parametrize("draw", sorted(SCENES))
def test_a_box_behind_an_occluder_is_two_targets_not_three(draw, tmp_path, capsys):
    """Two targets, one of them the occluder within 2 cm (the box's place the 3-4 spots
    cannot pin down: draw 23's fits started at the truth drift 0.7-2.4 m). Before: three,
    the third a sliver the final fit did not hold (BIC gain -20 and -11 with the others
    refitted)."""
    scene = tmp_path / "scene.yaml"
    scene.write_text(json.dumps(SCENES[draw]))
    assert cli(["simulate", str(scene), "--out", str(tmp_path / "f.h5")]) == 0
    capsys.readouterr()
    assert cli(["locate", str(tmp_path / "f.h5"), "--json"]) == 0
    answer = json.loads(capsys.readouterr().out)
    found = np.array([t["position"] for t in answer["targets"]])
    assert len(found) == 2, found
    # the file's frame is (-x, z, y) of the scene's (its scene_info says so)
    x, y, z = SCENES[draw]["targets"][1]["position"]
    assert np.min(np.linalg.norm(found - [-x, z, y], axis=1)) < 0.02
