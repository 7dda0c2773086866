"""Ground paths: shapes, waypoint splines, arc length, lookups and bad input."""

from __future__ import annotations

import json

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from emotive import paths as P
from emotive.errors import PathError


@pytest.mark.parametrize("name", sorted(P.SHAPES))
def test_every_shape_starts_at_origin_heading_plus_z(name):
    path = P.load_path(name)
    np.testing.assert_allclose(path.position(0.0), [0.0, 0.0], atol=1e-12)
    assert abs(path.heading(0.0)) < 0.02
    # Dense, evenly spaced samples: no piece much longer than the sample spacing.
    steps = np.diff(path.arc)
    assert steps.max() < 3 * P.SAMPLE_SPACING and steps.min() > 0


def test_line():
    path = P.line(7.0)
    assert path.length == pytest.approx(7.0)
    np.testing.assert_allclose(path.position([0.0, 3.5, 7.0, 9.0, -1.0]),
                               [[0, 0], [0, 3.5], [0, 7], [0, 7], [0, 0]], atol=1e-12)
    np.testing.assert_allclose(path.curvature(np.linspace(0, 7, 20)), 0.0, atol=1e-9)


@pytest.mark.parametrize("radius", [0.5, 2.0, 10.0])
def test_circle_length_curvature_and_wrap(radius):
    path = P.circle(radius)
    assert path.closed
    assert path.length == pytest.approx(2 * np.pi * radius, rel=1e-4)
    s = np.linspace(0, path.length, 50)
    # Turning to the left (positive curvature) with radius ``radius``.
    np.testing.assert_allclose(path.curvature(s), 1.0 / radius, rtol=1e-3)
    centre = np.array([radius, 0.0])
    # Within the sag of 1 cm chords (c^2 / 8r <= 2.5e-5 m).
    np.testing.assert_allclose(np.linalg.norm(path.position(s) - centre, axis=-1), radius,
                               atol=2.5e-5)
    # A quarter of the way round the agent is at (r, r), heading +X (yaw +pi/2).
    np.testing.assert_allclose(path.position(path.length / 4), [radius, radius], atol=1e-4)
    assert path.heading(path.length / 4) == pytest.approx(np.pi / 2, abs=1e-3)
    np.testing.assert_allclose(path.position(path.length + 1.0), path.position(1.0), atol=1e-9)


def test_figure8_loops_turn_left_then_right_and_cross_at_origin():
    path = P.figure8(2.0)
    s = np.linspace(0, path.length, 400, endpoint=False)
    k = path.curvature(s)
    first, second = k[20:180], k[220:380]
    assert (first > 0).all() and (second < 0).all()
    assert np.median(first) == pytest.approx(0.5, rel=0.15)
    assert np.median(-second) == pytest.approx(0.5, rel=0.15)
    np.testing.assert_allclose(path.position(path.length / 2), [0.0, 0.0], atol=0.02)
    # Curvature changes gradually: no jump between neighbouring samples.
    assert np.abs(np.diff(k)).max() < 0.1


def test_zigzag_alternates():
    path = P.zigzag(leg=3.0, angle=30.0, count=4)
    k = path.curvature(np.linspace(0, path.length, 600))
    signs = np.sign(k[np.abs(k) > 0.3])
    assert (np.diff(signs) != 0).sum() >= 3


def test_tangent_is_unit_and_matches_the_derivative():
    path = P.figure8()
    s = np.linspace(0.1, path.length - 0.1, 100)
    t = path.tangent(s)
    np.testing.assert_allclose(np.linalg.norm(t, axis=-1), 1.0, atol=1e-9)
    d = (path.position(s + 1e-3) - path.position(s - 1e-3)) / 2e-3
    np.testing.assert_allclose(t, d / np.linalg.norm(d, axis=-1, keepdims=True), atol=2e-2)


def test_arc_length_parameterisation():
    path = P.waypoints(np.array([[0, 0], [3, 4], [6, 0]]))
    s = np.linspace(0, path.length, 200)
    steps = np.linalg.norm(np.diff(path.position(s), axis=0), axis=1)
    np.testing.assert_allclose(steps, path.length / 199, rtol=1e-2)


def test_waypoints_pass_through_their_points_and_merge_repeats():
    pts = np.array([[0, 0], [1, 2], [1, 2], [3, 3], [5, 2]], dtype=float)
    path = P.waypoints(pts)
    _, dist = path.nearest(pts)
    np.testing.assert_allclose(dist, 0.0, atol=1e-3)
    np.testing.assert_allclose(path.position(path.length), [5, 2], atol=1e-9)
    assert path.length > np.linalg.norm(np.diff(pts, axis=0), axis=1).sum() - 1e-9


def test_two_waypoints_make_a_segment():
    path = P.waypoints(np.array([[1.0, 1.0], [4.0, 5.0]]))
    assert path.length == pytest.approx(5.0)
    assert path.heading(2.0) == pytest.approx(np.arctan2(3, 4))


@settings(max_examples=30, deadline=None)
@given(st.floats(-20, 20), st.floats(-20, 20))
def test_nearest_on_a_circle(x, z):
    path = P.circle(2.0)
    s, d = path.nearest(np.array([x, z]))
    centre_dist = np.hypot(x - 2.0, z)
    assert d == pytest.approx(abs(centre_dist - 2.0), abs=1e-3)
    np.testing.assert_allclose(np.linalg.norm(path.position(s) - [x, z]), d, atol=1e-6)


def test_nearest_is_batched():
    path = P.line(10.0)
    q = np.array([[[1.0, 2.0], [-0.5, 4.0]], [[0.0, 12.0], [0.0, -3.0]]])
    s, d = path.nearest(q)
    assert s.shape == d.shape == (2, 2)
    np.testing.assert_allclose(s, [[2.0, 4.0], [10.0, 0.0]], atol=1e-9)
    np.testing.assert_allclose(d, [[1.0, 0.5], [2.0, 3.0]], atol=1e-9)


class TestFiles:
    def test_list_and_object_forms(self, tmp_path):
        a = tmp_path / "a.json"
        a.write_text(json.dumps([[0, 0], [2, 1], [4, 0]]))
        b = tmp_path / "b.json"
        b.write_text(json.dumps({"points": [[0, 0], [2, 2], [4, 0], [2, -2]], "closed": True}))
        pa, pb = P.load_path(a), P.load_path(str(b))
        assert not pa.closed and pb.closed
        np.testing.assert_allclose(pb.position(pb.length), pb.position(0.0), atol=1e-9)
        # A closed spline has no corner where it joins itself.
        assert abs(np.angle(np.exp(1j * (pb.heading(1e-3) - pb.heading(pb.length - 1e-3))))) < 0.01

    @pytest.mark.parametrize(("content", "words"), [
        ("not json", "not valid JSON"),
        ('{"pts": []}', "must hold"),
        ("[[0, 0, 0], [1, 1, 1]]", "must hold"),
        ("[[0, 0]]", "at least two distinct points"),
        ("[[1, 1], [1, 1], [1, 1]]", "at least two distinct points"),
        ("[[0, 0], [1e9, 0]]", "metres"),
        ('[[0, 0], ["a", 0]]', "must hold"),
        ('{"points": [[0, 0], [1, 1]], "closed": "yes"}', "true or false"),
        ('{"points": [[0, 0], [1, 1]], "closed": true}', "three distinct points"),
    ])
    def test_bad_files(self, tmp_path, content, words):
        f = tmp_path / "bad.json"
        f.write_text(content)
        with pytest.raises(PathError, match=words) as info:
            P.load_path(f)
        assert "bad.json" in str(info.value)

    def test_missing_file_and_unknown_name(self, tmp_path):
        with pytest.raises(PathError, match="does not exist"):
            P.load_path(tmp_path / "nope.json")
        with pytest.raises(PathError, match="figure8"):
            P.load_path("figure-eight")


@pytest.mark.parametrize(("maker", "kwargs"), [
    (P.line, {"length": 0.0}), (P.circle, {"radius": -1.0}), (P.figure8, {"radius": np.nan}),
    (P.zigzag, {"angle": 95.0}), (P.zigzag, {"count": 0}), (P.line, {"length": 1e12}),
])
def test_bad_shape_sizes(maker, kwargs):
    with pytest.raises(PathError):
        maker(**kwargs)


def test_bad_points():
    with pytest.raises(PathError, match="finite"):
        P.waypoints(np.array([[0.0, 0.0], [np.nan, 1.0]]))
    with pytest.raises(PathError, match="pairs"):
        P.waypoints(np.zeros((3, 3)))
