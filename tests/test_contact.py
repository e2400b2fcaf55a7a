"""Contact signals observed with the hand: the object's marker and the grip aperture place grasps."""

import json

import numpy as np
import pytest

from besman.cli import main
from besman.core.errors import InputError
from besman.learning import Demonstration, DemonstrationError, SegmentationPrior, SegmentModel, segment
from besman.learning.segmentation.changepoints import (
    POLYNOMIAL_MODELS,
    STILL,
    JointModel,
    change_probabilities,
    joint_evidences,
    length_prior,
    log_marginal_likelihood,
    map_segmentation,
    pruned_map_segmentation,
    segment_evidences,
)
from besman.learning.segmentation.contact import OBJECT_AND_GRIP, ContactMarkers
from besman.learning.segmentation.segmenter import PRIOR_CHOICES, choose_prior
from besman.skills.transformation import minimum_jerk

RATE = 60.0
SPEED_MINIMUM = 1.6  # s: the reach ends; the hand creeps on, ever faster
CONTACT = 2.0  # s: it takes hold of the object and carries it off, 0.4 s later
CARRIED = 3.4  # s: the object is set down


def bump(times: np.ndarray, start: float, end: float) -> np.ndarray:
    """The velocity profile of a unit minimum-jerk displacement from ``start`` to ``end`` (s)."""
    s = np.clip((times - start) / (end - start), 0.0, 1.0)
    return np.gradient(minimum_jerk(s), times)


def grasp_after_creeping(seed: int, markers: tuple[str, ...]) -> Demonstration:
    """Hold, a reach that ends at 1.6 s, 0.4 s of creeping towards the object (speed rising from 0 to 6
    cm/s, kept up while carrying), a carry from 2.0 s to 3.4 s, hold. The hand is slowest where the reach
    ends but takes hold of the object at 2.0 s: from then on the object moves with the hand and the grip
    aperture stays constant; before, the object rests and the fingers close on it. Only ``markers`` are
    recorded besides the hand's; 0.2 mm noise."""
    rng = np.random.default_rng(seed)
    times = np.arange(round(4.2 * RATE)) / RATE
    creeping = np.clip((times - SPEED_MINIMUM) / (CONTACT - SPEED_MINIMUM), 0.0, 1.0) * (times < CARRIED)
    velocity = (
        np.outer(bump(times, 0.6, SPEED_MINIMUM), [0.3, 0.1, 0.0])
        + np.outer(0.06 * creeping, [0.0, 1.0, 0.0])
        + np.outer(bump(times, CONTACT, CARRIED), [0.0, 0.3, 0.1])
    )
    hand = np.cumsum(velocity, axis=0) / RATE
    held = times >= CONTACT
    box = np.where(held[:, None], hand - hand[np.argmax(held)], 0.0) + [0.4, 0.0, 0.0]
    closing = np.clip((CONTACT - times) / 0.8, 0.0, 1.0)  # the fingers close over the 0.8 s before
    aperture = 0.06 + 0.04 * closing**2 * (3 - 2 * closing)
    thumb = hand + [0.0, 0.0, -0.05]
    channels = {
        "Hand top": hand,
        "Box back": box,
        "Thumb": thumb,
        "Index": thumb + aperture[:, None] * [0.0, 1.0, 0.0],
    }
    return Demonstration(
        times=times,
        frames=np.arange(len(times)),
        channels={
            name: values + rng.normal(0.0, 0.0002, values.shape)
            for name, values in channels.items()
            if name == "Hand top" or name in markers
        },
        source="grasp.npz",
    )


@pytest.mark.parametrize(
    ("markers", "contact"),
    [(("Box back",), ContactMarkers(object="Box back", grip=None)), (("Thumb", "Index"), ContactMarkers())],
    ids=["object", "grip"],
)
def test_a_contact_signal_that_contradicts_the_speed_moves_the_boundary_where_the_contact_is(
    markers, contact
):
    """The hand alone puts the boundary between reach and carry where the hand is slowest; observed with the
    object's marker (or the grip), where the hand takes hold of the object."""
    for seed in range(3):
        demo = grasp_after_creeping(seed, markers)
        alone = segment(demo, contact=None)
        joint = segment(demo, contact=contact)
        assert len(alone) == len(joint) == 4, (alone.times, joint.times)  # hold, reach, carry, hold
        assert alone.times[2] == pytest.approx(SPEED_MINIMUM, abs=0.05)
        assert joint.times[2] == pytest.approx(CONTACT, abs=0.1)
        assert joint.holding[1:3] == (False, True) and not any(alone.holding)
        assert joint.models[2].endswith(", holding" if "Box back" in markers else ", steady grip")
        assert joint.signals[1:] == (
            ("object velocity (Box back)",)
            if "Box back" in markers
            else ("grip aperture rate (Thumb-Index)",)
        )
        assert joint.notes == ()


def test_a_recording_without_the_contact_markers_is_segmented_from_the_hand_alone_with_a_note():
    demo = grasp_after_creeping(0, ())
    alone = segment(demo, contact=None)
    found = segment(demo, contact=OBJECT_AND_GRIP)
    np.testing.assert_array_equal(found.frames, alone.frames)
    assert found.signals == ("hand velocity (Hand top)",)
    assert found.notes == (
        "no 'Box back' marker in the recording: segmented without the object velocity (Box back)",
        "no 'Thumb' marker in the recording: segmented without the grip aperture rate (Thumb-Index)",
    )
    gappy = grasp_after_creeping(0, ("Thumb", "Index"))
    gappy.channels["Index"][60:90] = np.nan  # 0.5 s missing: longer than the smoother bridges
    found = segment(gappy)
    assert found.signals == ("hand velocity (Hand top)",)
    assert found.notes[0].startswith("grasp.npz: marker 'Index' is missing for 0.50 s (frames 60-89)")


def test_segment_json_names_the_signals_used_and_the_notes(capsys, tmp_path):
    demo = grasp_after_creeping(1, ("Thumb",))
    path = demo.save(tmp_path / "grasp.npz")
    assert main(["segment", str(path), "--json"]) == 0
    result = json.loads(capsys.readouterr().out)
    assert result["signals"] == ["hand velocity (Hand top)"]
    assert result["notes"] == [
        "no 'Index' marker in the recording: segmented without the grip aperture rate (Thumb-Index)"
    ]
    assert result["prior"]["expected_length_s"] in PRIOR_CHOICES["expected_length"]
    assert np.isfinite(result["log_evidence"])
    assert main(["segment", str(path), "--json", "--object", "Box back"]) == 0
    assert "no 'Box back' marker" in json.loads(capsys.readouterr().out)["notes"][0]


def test_the_prior_is_the_one_of_highest_marginal_likelihood():
    """choose_prior against an independent evaluation of every candidate (forward-backward with the model
    prior built from the weights), and the forward-only marginal against forward-backward."""
    demo = grasp_after_creeping(2, ("Thumb", "Index"))
    chosen = segment(demo)
    assert chosen.log_evidence is not None
    found = segment(demo, prior=chosen.prior)
    np.testing.assert_array_equal(found.frames, chosen.frames)
    rng = np.random.default_rng(0)
    y = np.r_[rng.normal(0, 0.1, 12), rng.normal(1, 0.1, 10), rng.normal(0, 0.1, 14)]
    models = tuple(JointModel.of(m) for m in POLYNOMIAL_MODELS)
    base = SegmentationPrior(noise=0.1, min_length=0.1)
    evidences = [segment_evidences(y, 10.0, m.parts[0], base) for m in models]
    candidates = {}
    for expected in PRIOR_CHOICES["expected_length"]:
        for hold_weight in PRIOR_CHOICES["hold_weight"]:
            prior = SegmentationPrior(
                noise=0.1, min_length=0.1, expected_length=expected, hold_weight=hold_weight
            )
            log_g, log_survival = length_prior(len(y), 10.0, prior)
            weights = np.array([hold_weight if m.hold else 1.0 for m in models])
            marginal = change_probabilities(evidences, log_g, log_survival, np.log(weights / weights.sum()))[
                1
            ]
            candidates[expected, hold_weight] = marginal
    best, marginal = choose_prior(evidences, models, 10.0, base)
    assert max(candidates.values()) == pytest.approx(marginal, abs=1e-9)
    assert candidates[best.expected_length, best.hold_weight] == pytest.approx(marginal, abs=1e-9)
    combined = np.logaddexp.reduce(np.stack(evidences) + np.log(1 / 3), axis=0)
    log_g, log_survival = length_prior(len(y), 10.0, base)
    assert log_marginal_likelihood(combined, log_g, log_survival) == pytest.approx(
        change_probabilities(evidences, log_g, log_survival, np.log(np.full(3, 1 / 3)))[1], abs=1e-9
    )


def test_joint_evidences_add_up_and_pruned_inference_on_several_signals_is_exact_with_enough_particles():
    rng = np.random.default_rng(3)
    hand = np.r_[rng.normal(0, 0.1, (15, 2)), rng.normal(1, 0.1, (15, 2)), rng.normal(0, 0.1, (15, 2))]
    other = np.r_[rng.normal(0, 0.1, 15), rng.normal(2, 0.1, 15), rng.normal(0, 0.1, 15)]
    prior = SegmentationPrior(noise=0.1, min_length=0.2, hold_weight=1.0)
    models = tuple(
        JointModel(f"{hand_model.name} {k}", (hand_model, other_model), hold=hand_model.hold)
        for hand_model in POLYNOMIAL_MODELS[:2]
        for k, other_model in enumerate((STILL, POLYNOMIAL_MODELS[0]))
    )
    evidences = joint_evidences([hand, other], 10.0, models, [prior, prior])
    for model, evidence in zip(models, evidences, strict=True):
        expected = segment_evidences(hand, 10.0, model.parts[0], prior) + segment_evidences(
            other, 10.0, model.parts[1], prior
        )
        np.testing.assert_array_equal(evidence, expected)
    log_g, log_survival = length_prior(len(hand), 10.0, prior)
    model_prior = prior.log_model_prior(models)
    exact = map_segmentation(evidences, log_g, log_survival, model_prior)
    pruned = pruned_map_segmentation(
        [hand, other], 10.0, models, [prior, prior], prior, model_prior, len(hand) + 1, seed=0
    )
    np.testing.assert_array_equal(pruned[0], exact[0])
    np.testing.assert_array_equal(pruned[1], exact[1])
    np.testing.assert_array_equal(exact[0], [0, 15, 30, 45])


def test_bad_contact_settings_and_models_too_long_for_the_recording_are_refused_by_name():
    demo = grasp_after_creeping(0, ("Thumb", "Index"))
    with pytest.raises(InputError, match=r"contact must be None or ContactMarkers\(...\), got 'Box back'"):
        segment(demo, contact="Box back")
    with pytest.raises(
        InputError, match=r"ContactMarkers.grip must be two marker names or None, got \('Thumb',\)"
    ):
        ContactMarkers(grip=("Thumb",))
    with pytest.raises(InputError, match=r"ContactMarkers\.object must be a marker name or None, got 3"):
        ContactMarkers(object=3)
    too_long = (SegmentModel("long hold", degree=-1, min_length=5.0, hold=True),)
    with pytest.raises(
        DemonstrationError, match=r"grasp.npz: the recording lasts 4.18 s, shorter than the shortest"
    ):
        segment(demo, models=too_long)
