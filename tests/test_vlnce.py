"""VLN-CE export library: the Z-up -> habitat Y-up frame both ways, headings as habitat rotations,
habitat-style tokens and vocabulary, episode dicts with the fields habitat's VLNEpisode takes."""

from __future__ import annotations

import gzip
import json
import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from sagebench.scene.loader import frame_matrix
from sagebench.vlnce.episodes import dataset_bytes, habitat_episode, trajectory_number
from sagebench.vlnce.frame import from_habitat, rotation_to_yaw, to_habitat, yaw_to_rotation
from sagebench.vlnce.vocab import PAD_INDEX, UNK_INDEX, Vocabulary, tokenize

coords = st.floats(-1e3, 1e3, allow_nan=False)


def test_known_points_in_habitat_frame():
    # world up (+Z) is habitat up (+Y); world north (+Y) is habitat -Z (where an unturned agent looks)
    assert to_habitat([0, 0, 1]).tolist() == [0, 1, 0]
    assert to_habitat([0, 1, 0]).tolist() == [0, 0, -1]
    assert to_habitat([1, 0, 0]).tolist() == [1, 0, 0]
    assert to_habitat([2.0, 3.0, 0.5]).tolist() == [2.0, 0.5, -3.0]


@given(st.tuples(coords, coords, coords))
def test_frame_round_trips_both_ways(p):
    assert np.allclose(from_habitat(to_habitat(p)), p)
    assert np.allclose(to_habitat(from_habitat(p)), p)


@given(st.tuples(coords, coords, coords))
def test_habitat_frame_is_what_the_scene_loader_reads_as_y_up(p):
    """A habitat (Y-up) point loaded as a Y-up scene comes back as the world point it was made from."""
    assert np.allclose(frame_matrix("m", "Y")[:3, :3] @ to_habitat(p), p)


@given(st.floats(-math.pi + 1e-9, math.pi, allow_nan=False))
def test_rotation_faces_the_heading_and_round_trips(yaw):
    q = yaw_to_rotation(yaw)
    assert np.linalg.norm(q) == pytest.approx(1.0)
    forward = Rotation.from_quat(q).apply([0.0, 0.0, -1.0])  # habitat's agent looks along its -Z
    assert np.allclose(forward, to_habitat([math.cos(yaw), math.sin(yaw), 0.0]), atol=1e-9)
    assert rotation_to_yaw(q) == pytest.approx(yaw, abs=1e-9)


def test_facing_north_is_habitat_identity():
    assert np.allclose(yaw_to_rotation(math.pi / 2), [0, 0, 0, 1])


def test_tokenize_like_habitat():
    assert tokenize("Walk past the sofa's arm, then STOP?") == ["walk", "past", "the", "sofa", "'s", "arm", "then",
                                                                "stop"]
    assert tokenize("the grey-blue chair. Turn left!") == ["the", "grey-blue", "chair", "turn", "left"]


def test_vocabulary_starts_with_pad_and_unk_and_pads_to_length():
    vocab = Vocabulary.from_texts(["Go to the chair.", "go to the door"])
    assert vocab.word_list == ("<pad>", "<unk>", "<s>", "</s>", "chair", "door", "go", "the", "to")
    assert vocab.word_list[PAD_INDEX] == "<pad>" and vocab.word_list[UNK_INDEX] == "<unk>"
    assert vocab.encode("Go to the sofa", length=6) == [6, 8, 7, UNK_INDEX, PAD_INDEX, PAD_INDEX]
    assert vocab.encode("go go go", length=2) == [6, 6]
    assert vocab.to_text().splitlines()[:2] == ["<pad>", "<unk>"]


ROW = {
    "episode_id": "48fdb414defefee6", "trajectory_id": "97ab3384678a6799", "scene_id": "apt",
    "instruction_level": "low", "instruction_type": "Base_Action", "instruction_text": "Walk to the door.",
    "start_position": [10.0, 3.0, 0.0], "start_yaw": math.pi, "goal_position": [8.0, 5.0, 0.0], "goal_radius": 1.0,
    "reference_path": [[10.0, 3.0, 0.0, math.pi], [8.0, 3.0, 0.0, math.pi / 2], [8.0, 5.0, 0.0, math.pi / 2]],
    "geodesic_distance": 4.0,
}

# habitat-lab's VLNEpisode (NavigationEpisode + reference_path, instruction, trajectory_id) and its parts take
# exactly these keyword arguments (attrs classes: an unknown key is a TypeError)
EPISODE_KEYS = {"episode_id", "scene_id", "start_position", "start_rotation", "info", "goals", "start_room",
                "shortest_paths", "reference_path", "instruction", "trajectory_id", "scene_dataset_config",
                "additional_obj_config_paths"}
INSTRUCTION_KEYS = {"instruction_text", "instruction_tokens"}
GOAL_KEYS = {"position", "radius"}


def check_habitat_episode(ep: dict) -> None:
    """The field types habitat-lab's VLN dataset loader builds its episode objects from."""
    assert set(ep) <= EPISODE_KEYS
    assert isinstance(ep["episode_id"], str) and isinstance(ep["scene_id"], str)
    assert isinstance(ep["trajectory_id"], int)
    for key, n in (("start_position", 3), ("start_rotation", 4)):
        assert len(ep[key]) == n and all(isinstance(v, float) for v in ep[key])
    assert isinstance(ep["info"], dict) and isinstance(ep["info"]["geodesic_distance"], float)
    assert set(ep["instruction"]) == INSTRUCTION_KEYS and isinstance(ep["instruction"]["instruction_text"], str)
    assert all(isinstance(t, int) for t in ep["instruction"]["instruction_tokens"])
    for goal in ep["goals"]:
        assert set(goal) == GOAL_KEYS and len(goal["position"]) == 3 and isinstance(goal["radius"], float)
    assert all(len(p) == 3 and all(isinstance(v, float) for v in p) for p in ep["reference_path"])


def test_episode_in_habitat_frame_with_habitat_types():
    vocab = Vocabulary.from_texts([ROW["instruction_text"]])
    ep = habitat_episode(ROW, vocab)
    check_habitat_episode(ep)
    assert ep["start_position"] == [10.0, 0.0, -3.0] and ep["goals"][0]["position"] == [8.0, 0.0, -5.0]
    assert ep["reference_path"] == [[10.0, 0.0, -3.0], [8.0, 0.0, -3.0], [8.0, 0.0, -5.0]]
    assert rotation_to_yaw(ep["start_rotation"]) == pytest.approx(math.pi)
    assert ep["scene_id"] == "apt/apt.glb" and ep["trajectory_id"] == 0x97AB3384678A6
    assert ep["info"]["geodesic_distance"] == 4.0 and len(ep["instruction"]["instruction_tokens"]) == 200


def test_dataset_file_is_gzipped_json_with_the_vocabulary_and_stable_bytes():
    vocab = Vocabulary.from_texts([ROW["instruction_text"]])
    data = dataset_bytes([ROW], vocab)
    assert data == dataset_bytes([ROW], vocab)
    parsed = json.loads(gzip.decompress(data))
    assert parsed["instruction_vocab"]["word_list"] == list(vocab.word_list)
    assert [e["episode_id"] for e in parsed["episodes"]] == ["48fdb414defefee6"]


def test_trajectory_numbers_are_exact_json_integers():
    assert trajectory_number("ffffffffffffffff") == 2**52 - 1
