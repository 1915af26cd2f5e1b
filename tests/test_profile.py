"""Profiles (mcl.profile), the localizer's odometry calibration and its log evidence."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from field import LandmarkType, spl
from mcl.localizer import Localizer
from mcl.profile import SECTIONS, Profile, ProfileError, default_values
from mcl.rivals import RivalSettings
from motion_models import MotionInput
from sensing import LandmarkSensorModel
from sensing.observations import Observations

FIELD = spl()


def _frame(kind=LandmarkType.CENTER_MARK, r=2.0, b=0.3):
    return Observations.from_arrays(np.array([int(kind)]), np.array([r]), np.array([b]))


# -- profiles --------------------------------------------------------------------------------------------------
values = st.fixed_dictionaries(
    {},
    optional={
        "sensor.range_noise_floor": st.floats(0.01, 1.0),
        "sensor.outlier_weight": st.floats(1e-4, 1.0),
        "sensor.mixture": st.sampled_from(["max", "sum"]),
        "motion.beta1": st.floats(0.0, 10.0),
        "odometry.scale_x": st.floats(0.5, 2.0),
        "augmented.fit_threshold": st.floats(0.0, 1.0),
        "quality.superb_detections": st.integers(1, 10),
        "rivals.young": st.floats(0.0, 10.0),
        "rivals.keep": st.integers(1, 32),
        "localizer.particles": st.integers(1, 2000),
        "localizer.compensate_latency": st.booleans(),
    },
)


@settings(max_examples=60, deadline=None)
@given(values)
def test_profile_round_trips_bit_for_bit(chosen):
    profile = Profile.from_values(chosen)
    again = Profile.from_toml(profile.to_toml(header=["a comment"]))
    assert again.values() == profile.values() == {k: v for k, v in chosen.items()}
    for key, value in again.values().items():
        assert type(value) is type(chosen[key])


def test_profile_sets_what_it_names_and_keeps_the_rest(tmp_path):
    path = tmp_path / "venue.toml"
    Profile.from_values(
        {
            "sensor.outlier_weight": 0.02,
            "odometry.scale_x": 1.2,
            "motion.beta1": 2.5,
            "localizer.particles": 123,
            "augmented.fit_threshold": 0.1,
            "relocalization.kidnap_share": 0.2,
            "quality.superb_fit": 0.6,
            "rivals.young": 3.0,
        }
    ).save(path)
    loc = Localizer.from_profile(FIELD, Profile.load(path), seed=4)
    assert loc.filter.sensor_model.outlier_weight == 0.02
    assert loc.filter.sensor_model.range_noise_floor == LandmarkSensorModel(FIELD).range_noise_floor
    assert loc.odometry_scale == (1.2, 1.0, 1.0)
    assert loc.filter.motion_model.beta1 == 2.5 and loc.filter.motion_model.beta2 == 1.0
    assert loc.filter.poses.shape[0] == 123
    assert loc.filter.augmented.fit_threshold == 0.1
    assert loc.thresholds.superb_fit == 0.6
    assert loc.thresholds.rivals.young == 3.0 and loc.thresholds.rivals.keep == RivalSettings().keep
    # an override wins over the profile
    assert Localizer.from_profile(FIELD, Profile.load(path), n_particles=50).filter.poses.shape[0] == 50
    with pytest.raises(TypeError, match="Profile.load"):
        Localizer.from_profile(FIELD, str(path))


def test_an_empty_profile_is_the_defaults_bit_for_bit():
    a, b = Localizer.from_profile(FIELD, Profile(), seed=7), Localizer(FIELD, seed=7)
    for loc in (a, b):
        loc.anywhere_in_own_half()
        for k in range(30):
            loc.motion(0.01 * (k + 1), MotionInput(0.01, odometry=(0.002, 0.0, 0.001)))
            if k % 5 == 0:
                loc.observe(_frame(r=2.0 + 0.01 * k))
    assert np.array_equal(a.filter.poses, b.filter.poses)
    assert a.log_evidence == b.log_evidence


@pytest.mark.parametrize(
    "sections, words",
    [
        ({"venue": {}}, "unknown section [venue]"),
        ({"sensor": {"noise": 1.0}}, "unknown setting 'noise'"),
        ({"sensor": {"outlier_weight": "high"}}, "must be a number"),
        ({"sensor": {"outlier_weight": -0.1}}, "outlier_weight"),
        ({"sensor": {"mixture": "mean"}}, "mixture"),
        ({"localizer": {"particles": 2.5}}, "must be an integer"),
        ({"localizer": {"compensate_latency": 1}}, "true or false"),
        ({"motion": {"model": "teleport"}}, "must be one of"),
        ({"motion": {"model": "constant", "beta1": 1.0}}, "not a setting of the 'constant' model"),
        ({"odometry": {"scale_x": 0.0}}, "odometry_scale"),
        ({"augmented": {"alpha_slow": 0.5, "alpha_fast": 0.1}}, "alpha_slow"),
        ({"sensor": 3}, "must be a table"),
        ({"rivals": {"drop_odds": 0.5}}, "drop_odds"),
    ],
)
def test_a_wrong_profile_is_refused_in_one_line_naming_the_file(sections, words):
    with pytest.raises(ProfileError) as error:
        Profile(sections, "venue.toml")
    message = str(error.value)
    assert message.startswith("venue.toml: ") and words in message and "\n" not in message


def test_a_profile_that_is_not_toml_is_refused(tmp_path):
    path = tmp_path / "p.toml"
    path.write_text("[sensor\n")
    with pytest.raises(ProfileError, match="not TOML"):
        Profile.load(path)
    with pytest.raises(OSError):
        Profile.load(tmp_path / "missing.toml")


def test_every_section_setting_has_a_default():
    defaults = default_values()
    for section, settings_ in SECTIONS.items():
        for name in settings_:
            assert f"{section}.{name}" in defaults, (section, name)


# -- odometry calibration ----------------------------------------------------------------------------------------
def test_odometry_scale_is_the_same_as_scaled_odometry_bit_for_bit():
    scaled = Localizer(FIELD, seed=3, odometry_scale=(1.25, 0.5, 2.0))
    plain = Localizer(FIELD, seed=3)
    for loc in (scaled, plain):
        loc.place((0.0, 0.0, 0.3))
    for k in range(20):
        scaled.motion(0.01 * (k + 1), MotionInput(0.01, odometry=(0.004, 0.002, 0.01)))
        plain.motion(0.01 * (k + 1), MotionInput(0.01, odometry=(1.25 * 0.004, 0.5 * 0.002, 2.0 * 0.01)))
    assert np.array_equal(scaled.filter.poses, plain.filter.poses)


@pytest.mark.parametrize(
    "scale", [(0.0, 1.0, 1.0), (1.0, -1.0, 1.0), (1.0, 1.0, 11.0), (1.0, math.nan, 1.0), (1.0, 1.0)]
)
def test_a_wrong_odometry_scale_is_refused(scale):
    with pytest.raises(ValueError):
        Localizer(FIELD, odometry_scale=scale)


# -- evidence ------------------------------------------------------------------------------------------------------
def test_log_normalizer_makes_a_density_over_range_and_bearing():
    """One candidate landmark (the centre mark), the sum mixture and a negligible floor: the frame's density
    integrates to 1 over range and bearing."""
    model = LandmarkSensorModel(
        FIELD, mixture="sum", outlier_weight=1e-12, range_noise_floor=0.1, range_noise_growth=0.0, bearing_sigma=0.1
    )
    pose = np.array([[-2.0, 0.5, 0.2]])
    ranges = np.linspace(1.0, 3.2, 441)
    bearings = np.linspace(-1.05, 0.15, 401)  # the centre mark is seen at -0.445 rad
    density = np.empty((ranges.size, bearings.size))
    for i, r in enumerate(ranges):
        for j, b in enumerate(bearings):
            obs = _frame(r=r, b=b)
            density[i, j] = math.exp(model.log_likelihood(pose, obs)[0] + model.log_normalizer(obs))
    total = np.trapezoid(np.trapezoid(density, bearings, axis=1), ranges)
    assert total == pytest.approx(1.0, abs=2e-3)


def test_log_evidence_sums_the_frames_and_a_refused_frame_changes_nothing():
    loc = Localizer(FIELD, seed=1)
    loc.place((-2.0, 0.5, 0.2))
    loc.motion(0.01, MotionInput(0.01, odometry=(0.0, 0.0, 0.0)))
    total = 0.0
    for r in (2.0, 2.1, 1.9):
        frame = _frame(r=r)
        loc.observe(frame)
        total += loc.filter.frame_log_likelihood + loc.filter.sensor_model.log_normalizer(frame)
    assert loc.evidence_frames == 3 and loc.log_evidence == total
    with pytest.raises(ValueError):
        loc.observe(
            Observations.from_arrays(np.array([int(LandmarkType.CENTER_MARK)]), np.array([-1.0]), np.array([0.0]))
        )
    assert loc.evidence_frames == 3 and loc.log_evidence == total
    loc.observe(Observations.from_arrays(np.zeros(0, np.int64), np.zeros(0), np.zeros(0)))  # nothing seen
    assert loc.evidence_frames == 3


def test_evidence_prefers_the_noise_the_detections_have():
    """Detections drawn with σ_r = 0.2 m, none false: the evidence is higher for a model with that noise than
    for one ten times tighter or five times wider. (The outlier floor is relative to a perfect match, so its
    density grows as σ shrinks: with the default floor a tight model pays for the outliers it claims.)"""
    truth = np.array([-1.5, 1.0, 0.4])
    landmarks = FIELD.landmarks_of(LandmarkType.L_CROSSING)
    evidence = {}
    for sigma in (0.02, 0.2, 1.0):
        loc = Localizer(
            FIELD,
            sensor_model=LandmarkSensorModel(
                FIELD, range_noise_floor=sigma, range_noise_growth=0.0, outlier_weight=1e-5
            ),
            seed=2,
        )
        loc.place(truth)
        draw = np.random.default_rng(5)
        for k in range(40):
            loc.motion(0.05 * (k + 1), MotionInput(0.05, odometry=(0.0, 0.0, 0.0)))
            d = landmarks - truth[:2]
            r = np.hypot(d[:, 0], d[:, 1]) + 0.2 * draw.standard_normal(len(landmarks))
            b = np.arctan2(d[:, 1], d[:, 0]) - truth[2] + 0.05 * draw.standard_normal(len(landmarks))
            near = (r < 5.0) & (np.abs(np.angle(np.exp(1j * b))) < 1.0)
            loc.observe(
                Observations.from_arrays(
                    np.full(int(near.sum()), int(LandmarkType.L_CROSSING)), r[near], np.angle(np.exp(1j * b[near]))
                )
            )
        evidence[sigma] = loc.log_evidence
    assert evidence[0.2] > evidence[0.02] and evidence[0.2] > evidence[1.0]


@settings(max_examples=40, deadline=None)
@given(
    st.lists(
        st.tuples(
            st.floats(0.1, 12.0),
            st.one_of(st.none(), st.floats(0.01, 2.0)),
            st.one_of(st.none(), st.floats(0.005, 3.0)),
        ),
        min_size=1,
        max_size=8,
    ),
    st.sampled_from(["von_mises", "exact"]),
    st.floats(1e-6, 1.0),
    st.floats(0.0, 0.3),
)
def test_log_normalizer_is_its_formula(rows, bearing_model, outlier_weight, linear):
    """The per-detection loop against the formula in numpy (scipy's i0e), with and without the detections' own
    noise figures."""
    from scipy.special import i0e

    model = LandmarkSensorModel(
        FIELD, bearing_model=bearing_model, outlier_weight=outlier_weight, range_noise_linear=linear
    )
    ranges = np.array([r for r, _, _ in rows])
    range_sigmas = np.array([np.nan if s is None else s for _, s, _ in rows])
    bearing_sigmas = np.array([np.nan if s is None else s for _, _, s in rows])
    obs = Observations.from_arrays(
        np.full(len(rows), int(LandmarkType.GOALPOST)),
        ranges,
        np.zeros(len(rows)),
        range_sigmas=range_sigmas,
        bearing_sigmas=bearing_sigmas,
    )
    sr = np.where(np.isnan(range_sigmas), model.range_sigma(ranges), range_sigmas)
    sb = np.where(np.isnan(bearing_sigmas), model.bearing_sigma, bearing_sigmas)
    log_b = -np.log(2 * np.pi * i0e(1 / sb**2)) if bearing_model == "von_mises" else -np.log(np.sqrt(2 * np.pi) * sb)
    log_c = -np.log(np.sqrt(2 * np.pi) * sr) + log_b
    d = FIELD.dims
    area = 2 * np.pi * np.hypot(d.length + 2 * d.border_strip_width, d.width + 2 * d.border_strip_width)
    expected = float(np.sum(log_c - np.logaddexp(0.0, log_c + np.log(outlier_weight * area))))
    assert model.log_normalizer(obs) == pytest.approx(expected, rel=1e-12, abs=1e-9)
