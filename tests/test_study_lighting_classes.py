"""Study part `lighting-classes` (issue 36 goal 5): every lighting mode's error per pixel
against its cost, per class of map, the held-out maps marked."""

import numpy as np

from brdflab.lighting.synthetic_maps import CLASSES, catalogue
from brdflab.study.framework import StudyContext
from brdflab.study import lighting_classes as part


def test_the_quick_run_keeps_every_class_and_a_held_out_map_of_each():
    chosen = part.maps(quick=True)
    assert {s.kind for s in chosen} == set(CLASSES)
    for kind in CLASSES:
        if any(s.held_out for s in catalogue() if s.kind == kind):
            assert any(s.held_out for s in chosen if s.kind == kind)
        assert any(not s.held_out for s in chosen if s.kind == kind)
    assert len(part.maps(quick=False)) == len(catalogue())


def test_its_numbers_are_errors_against_quadrature_and_the_chart_marks_held_out_maps(tmp_path):
    """A Lambertian under prefiltered lighting is exact but for the map's texels (0.2–1.8 % on
    these 64 × 32 maps, 0.1–1.1 % at 128 × 64); FIS at 16 samples is 30–60 % off."""
    specs = [s for s in part.maps(quick=True) if s.kind in ("sun", "night")]
    numbers = part.measure_maps({"Lambertian": part.MATERIALS["Lambertian"]}, specs,
                                [("prefiltered", None), ("fis", 16)], 16, 16, (64, 32), StudyContext(quick=True))
    entry = numbers["materials"]["Lambertian"]
    assert [r["map"] for r in entry["rows"]] == [s.name for s in specs]
    assert [r["held_out"] for r in entry["rows"]] == [s.held_out for s in specs]
    prefiltered = np.array([r["errors"]["prefiltered"] for r in entry["rows"]])
    fis = np.array([r["errors"]["fis 16"] for r in entry["rows"]])
    assert (prefiltered < 0.02).all() and (fis > 5 * prefiltered).all()
    assert set(entry["frame_ms"]) == {"prefiltered", "fis 16"} and min(entry["frame_ms"].values()) > 0
    words = part.within_goal(numbers)
    assert words == [f"Lambertian: ≤ 64 samples within 2 % on {len(specs)} of {len(specs)} maps "
                     f"({sum(s.held_out for s in specs)} of {sum(s.held_out for s in specs)} held out); within it "
                     f"everywhere: prefiltered ({entry['frame_ms']['prefiltered']:.1f} ms)"]
    assert part.draw(numbers, tmp_path) == ["lighting_classes.png"]
    assert (tmp_path / "lighting_classes.png").stat().st_size > 10_000


def test_a_cancelled_run_returns_what_it_has():
    numbers = part.measure_maps(dict(part.MATERIALS), part.maps(quick=True), part.QUICK_SETTINGS, 16, 16, (64, 32),
                                StudyContext(quick=True, cancelled=lambda: True))
    assert numbers["materials"] == {}
