"""Calibration recovers a known mismatch; the result drives reconstruction;
progress callbacks and the GIL."""

import json
import threading
import time

import numpy as np
import pytest

import cassi

# cassi.simulate's discrete operators put each band's light at one position;
# calibrate's default spreads it (a camera's continuous spectrum), so the
# calibrations of their data say so
POINT = "point"

TRUTH = {"dx": 1.3, "dy": -0.8, "theta_deg": 0.35, "a1": 2.0, "alpha_deg": 0.0, "blur_sigma_px": 0.0}


@pytest.fixture(scope="module")
def case():
    scene = cassi.synthetic_scene(96, 96, 8, seed=5)
    mask = cassi.random_mask(96, 96, seed=2)
    y = cassi.simulate(scene, mask, TRUTH, model="rounded", noise=False)
    return scene, mask, y


def test_calibration_recovers_a_known_misalignment(case):
    _, mask, y = case
    seen = []
    cal = cassi.calibrate(y, mask, bands=8, model="rounded", progress=seen.append)
    e = cal.parameters
    assert list(e) == cassi.PARAMETERS
    assert abs(e["dx"] - TRUTH["dx"]) < 0.1, e
    assert abs(e["dy"] - TRUTH["dy"]) < 0.1, e
    assert abs(e["theta_deg"] - TRUTH["theta_deg"]) < 0.15, e
    assert abs(e["a1"] - TRUTH["a1"]) < 0.03, e
    assert cal.score < cal.nominal_score / 2
    assert (cal.preset, cal.model) == ("default", "rounded")
    # standard errors: the registry's keys; the rounded model states the pose's
    se = cal.standard_errors
    assert list(se) == cassi.PARAMETERS
    assert all(se[k] is not None and se[k] > 0 for k in ["dx", "dy", "theta_deg"])
    # the rounded model has no texture fit: no 95 % interval
    assert list(cal.intervals_95) == cassi.PARAMETERS
    assert all(v is None for v in cal.intervals_95.values())
    # the progress callback saw every stage, in order, as the result lists them
    assert [s["name"] for s in seen] == [s["name"] for s in cal.stages]
    assert len(seen) >= 3
    assert cal.seconds > 0 and cal.evaluations >= sum(s["evaluations"] for s in cal.stages)
    assert isinstance(cal.trade_offs, list)
    # the JSON form round-trips
    again = cassi.Calibration.from_json(cal.to_json())
    assert again.parameters == cal.parameters and again.standard_errors == se
    assert "dx" in repr(cal) and "±" in repr(cal)


def test_default_calibration_reports_trade_offs_and_blur(case):
    scene, mask, _ = case
    truth = dict(TRUTH, a1=2.05, alpha_deg=1.5)
    y = cassi.simulate(scene, mask, truth, model="dispersed-mask", noise=False)
    cal = cassi.calibrate(y, mask, bands=8, band_spread=POINT)  # dispersed-mask is the default
    e = cal.parameters
    assert cal.model == "dispersed-mask"
    assert abs(e["a1"] - 2.05) < 0.02 and abs(e["alpha_deg"] - 1.5) < 0.5, e
    assert e["blur_sigma_px"] < 0.1
    se, wide = cal.standard_errors, cal.intervals_95
    fitted = cassi.CALIBRATED_PARAMETERS
    assert all(se[k] is not None and se[k] > 0 for k in fitted), se
    # the curvature is held (at 0 here), not estimated
    assert e["a2"] == 0 and se["a2"] is None and "a2" not in fitted
    # the 95 % half-width carries its own (larger) floor: wider than 2 σ's floor alone
    assert all(wide[k] is not None and wide[k] > se[k] for k in fitted), (wide, se)
    assert "95 %" in repr(cal)
    assert cassi.Calibration.from_json(cal.to_json()).intervals_95 == wide
    # the ranges: estimate ∓ half-width, a blur's low end raised to 0 (σ here is near 0,
    # its half-width not: the range says "bounded above only" rather than reaching below 0)
    ranges = cal.ranges_95
    for k in fitted:
        low, high = ranges[k]
        assert abs(high - (e[k] + wide[k])) < 1e-12, (k, ranges[k], e[k], wide[k])
        want_low = max(e[k] - wide[k], 0.0) if k == "blur_sigma_px" else e[k] - wide[k]
        assert abs(low - want_low) < 1e-12, (k, ranges[k], e[k], wide[k])
    assert ranges["a2"] is None
    assert e["blur_sigma_px"] < wide["blur_sigma_px"] and ranges["blur_sigma_px"][0] == 0.0
    assert "bounded above only" in repr(cal)
    # a curvature given is held and comes back in the parameters
    bent = cassi.calibrate(y, mask, bands=8, band_spread=POINT, dispersion_a2=-0.004)
    assert bent.parameters["a2"] == -0.004
    # it also ran the fits from the nominal a1 and names the answer it passed over
    restart = cassi.CHOOSING_STAGES["nominal_a1_restart"]
    chose = [s for s in bent.stages if s["name"] == restart]
    assert len(chose) == 1 and chose[0]["passed_over"]["score"] >= chose[0]["score"], chose
    assert not [s for s in cal.stages if s["name"] == restart]
    # only the choosing stages name a passed-over answer, which scored no better
    # (a1 2.05 may also run the scene fit's nominal start, in the restart's fits
    # too, whose names carry a prefix)
    choosing = tuple(cassi.CHOOSING_STAGES.values())
    for s in cal.stages + bent.stages:
        other = s["passed_over"]
        assert other is None or (s["name"].endswith(choosing) and other["score"] >= s["score"]), s
    with pytest.raises(ValueError, match="a2"):
        cassi.calibrate(y, mask, bands=8, band_spread=POINT, dispersion_a2=0.9)
    for a, b, corr in cal.trade_offs:
        assert a in cassi.PARAMETERS and b in cassi.PARAMETERS and abs(corr) >= 0.8


def test_snapshots_of_one_instrument_combine_into_one_calibration(case):
    """Two snapshots (two scenes, one instrument) combined: the mean of their
    answers, wider errors where they disagree, usable for reconstruction."""
    scene, mask, _ = case
    other = cassi.synthetic_scene(96, 96, 8, seed=9)
    cals = [
        cassi.calibrate(cassi.simulate(s, mask, TRUTH, model="rounded", noise=False), mask, bands=8, model="rounded")
        for s in (scene, other)
    ]
    both = cassi.combine_calibrations(cals)
    assert both.model == "rounded" and cals[0].snapshots is None
    for k in ["dx", "dy", "theta_deg"]:
        mean = 0.5 * (cals[0].parameters[k] + cals[1].parameters[k])
        assert abs(both.parameters[k] - mean) < 1e-12, k
        assert abs(both.parameters[k] - TRUTH[k]) < 0.15, both.parameters
        # never tighter than the snapshots' stated errors combined as independent
        alone = np.hypot(cals[0].standard_errors[k], cals[1].standard_errors[k]) / 2
        assert both.standard_errors[k] >= alone - 1e-12
    spread = both.snapshots
    assert spread["parameters"] == [c.parameters for c in cals]
    assert {c["parameter"] for c in spread["consistency"]} <= set(cassi.CALIBRATED_PARAMETERS)
    # of two snapshots neither is farther out than the other
    assert all(c["farthest"] is None for c in spread["consistency"])
    assert [s["name"] for s in both.stages] == ["snapshot 0", "snapshot 1"]
    again = cassi.Calibration.from_json(both.to_json())
    assert again.snapshots == spread
    y = cassi.simulate(scene, mask, TRUTH, model="rounded", noise=False)
    x = cassi.reconstruct(y, mask, calibration=both, bands=8, iterations=5)
    assert x.shape == (8, 96, 96)
    with pytest.raises(cassi.InputError, match="two or more"):
        cassi.combine_calibrations(cals[:1])
    as_json = json.loads(cals[1].to_json())
    as_json["model"] = "subpixel"
    sub = cassi.Calibration.from_json(json.dumps(as_json))
    with pytest.raises(cassi.InputError, match="snapshot 1"):
        cassi.combine_calibrations([cals[0], sub])


def test_snapshots_refit_jointly_on_their_measurements(case):
    """Two snapshots of one blurred instrument (the crisp-cell model's data, not
    the model fitted) refitted as one: the geometry moves from the combination
    (kept), σ and the error bars stay its; bad measurements are refused."""
    scene, mask, _ = case
    truth = dict(TRUTH, dx=0.6, dy=-0.3, theta_deg=0.0, a1=2.02, blur_sigma_px=0.4)
    scenes = [scene, cassi.synthetic_scene(96, 96, 8, seed=9)]
    ys = [cassi.simulate(s, mask, truth, model="crisp-cells", noise=False) for s in scenes]
    cals = [cassi.calibrate(y, mask, bands=8, band_spread=POINT) for y in ys]
    plain = cassi.combine_calibrations(cals)
    joint = cassi.combine_calibrations(cals, measurements=ys, mask=mask, bands=8)
    assert joint.snapshots["joint_fit_from"] == plain.parameters
    assert plain.snapshots["joint_fit_from"] is None
    assert joint.parameters["blur_sigma_px"] == plain.parameters["blur_sigma_px"]
    assert joint.standard_errors == plain.standard_errors
    assert joint.parameters != plain.parameters
    assert len(joint.stages) == len(plain.stages) + 2
    assert joint.stages[-1]["name"].startswith("joint fit's fine pass")
    assert abs(joint.parameters["dx"] - truth["dx"]) < 0.15, joint.parameters
    assert cassi.Calibration.from_json(joint.to_json()).snapshots == joint.snapshots
    with pytest.raises(cassi.InputError, match="1 for 2 calibrations"):
        cassi.combine_calibrations(cals, measurements=ys[:1], mask=mask, bands=8)
    with pytest.raises(cassi.InputError, match="needs the mask"):
        cassi.combine_calibrations(cals, measurements=ys, bands=8)
    with pytest.raises(cassi.InputError, match=r"measurements\[1\]"):
        cassi.combine_calibrations(cals, measurements=[ys[0], ys[1][:10]], mask=mask, bands=8)
    rounded = [cassi.calibrate(y, mask, bands=8, model="rounded") for y in ys]
    with pytest.raises(cassi.InputError, match="does not run"):
        cassi.combine_calibrations(rounded, measurements=ys, mask=mask, bands=8)


def test_the_blur_pass_refits_the_blur_alone_last(case):
    scene, mask, _ = case
    truth = dict(TRUTH, blur_sigma_px=0.6)
    y = cassi.simulate(scene, mask, truth, model="crisp-cells", noise=False)
    # the default preset's own last stage (since stop 41); False leaves it out
    cal = cassi.calibrate(y, mask, bands=8, band_spread=POINT)
    *_, before, last = cal.stages
    assert last["name"].startswith("blur pass"), last
    without = cassi.calibrate(y, mask, bands=8, band_spread=POINT, blur_pass=False)
    assert without.stages[-1]["name"] == before["name"], without.stages[-1]
    assert without.parameters == before["parameters"]
    assert cal.parameters == last["parameters"]
    # since stop 63 the calibrated model reconstructs with the pass's σ
    assert cal.reconstruction_parameters == cal.parameters
    assert without.reconstruction_parameters == without.parameters
    for k in ["dx", "dy", "theta_deg", "a1", "alpha_deg"]:
        assert last["parameters"][k] == before["parameters"][k], k
    # on the crisp-cell model's own data it moves σ toward the truth
    was = abs(before["parameters"]["blur_sigma_px"] - 0.6)
    now = abs(last["parameters"]["blur_sigma_px"] - 0.6)
    assert now < was, (was, now)
    with pytest.raises(ValueError, match="blur_pass"):
        cassi.calibrate(y, mask, bands=8, preset="paper", blur_pass=True)


def test_search_rows_puts_the_search_stages_on_a_band(case):
    scene, mask, y = case
    every = cassi.calibrate(y, mask, bands=8, band_spread=POINT, blur_pass=False, search_rows="all")
    default = cassi.calibrate(y, mask, bands=8, band_spread=POINT, blur_pass=False)
    # a frame no taller than 256 rows searches on every row by default
    assert every.parameters == default.parameters
    band = cassi.calibrate(y, mask, bands=8, band_spread=POINT, blur_pass=False, search_rows=16)
    # the search stages score the band: another score at stage 1
    assert band.stages[1]["name"] == every.stages[1]["name"]
    assert abs(band.stages[1]["score"] / every.stages[1]["score"] - 1) > 1e-3
    for bad in (0, -3, "some", 2.5):
        with pytest.raises(ValueError, match="search_rows"):
            cassi.calibrate(y, mask, bands=8, band_spread=POINT, search_rows=bad)
    with pytest.raises(ValueError, match="search_rows"):
        cassi.calibrate(y, mask, bands=8, preset="paper", search_rows=64)


def test_ridge_probes_report_their_profiles_and_keep_the_answer(case):
    scene, mask, _ = case
    y = cassi.simulate(scene, mask, dict(TRUTH, a1=2.03), model="dispersed-mask", noise=False)
    plain = cassi.calibrate(y, mask, bands=8, band_spread=POINT, blur_pass=False)
    assert plain.ridge_probes is None
    probed = cassi.calibrate(y, mask, bands=8, band_spread=POINT, blur_pass=False, ridge_probes=True)
    # the probes keep the answer; the errors only widen
    assert probed.parameters == plain.parameters
    for k, s in plain.standard_errors.items():
        assert s is None or probed.standard_errors[k] >= s - 1e-12, k
    report = probed.ridge_probes
    assert [(p["ridge"], p["moved"]) for p in report["profiles"]] == [
        ("dx_a1", "first"), ("dx_a1", "last"), ("dy_alpha", "first"), ("dy_alpha", "last")
    ]
    for p in report["profiles"]:
        # the answer itself at step 0, relative objective 0
        i = p["steps_px"].index(0.0)
        assert p["relative_objective"][i] == 0.0
        assert len(p["steps_px"]) == len(p["relative_objective"]) == 13
    for e in report["ends"]:
        assert e["alternative"] == (e["relative_objective"] <= 0.01 and e["distance_px"] >= 0.5)
    assert json.loads(probed.to_json())["ridge_probes"]["profiles"]
    with pytest.raises(ValueError, match="ridge_probes"):
        cassi.calibrate(y, mask, bands=8, preset="paper", ridge_probes=True)


def test_fit_curvature_reports_a2_with_its_error(case):
    scene, mask, _ = case
    y = cassi.simulate(scene, mask, dict(TRUTH, a1=2.03), model="dispersed-mask", noise=False)
    held = cassi.calibrate(y, mask, bands=8, band_spread=POINT, blur_pass=False)
    assert held.standard_errors["a2"] is None and held.parameters["a2"] == 0.0
    fitted = cassi.calibrate(y, mask, bands=8, band_spread=POINT, blur_pass=False, fit_curvature=True)
    # a straight instrument: the curvature stays small, with its own error
    assert abs(fitted.parameters["a2"]) < 0.01
    assert fitted.standard_errors["a2"] > 0
    with pytest.raises(ValueError, match="fit_curvature"):
        cassi.calibrate(y, mask, bands=8, preset="paper", fit_curvature=True)


def test_a_band_table_is_held_and_travels_to_the_reconstruction(case):
    scene, mask, _ = case
    y = cassi.simulate(scene, mask, TRUTH, model="dispersed-mask", noise=False)
    # band 2 lands 0.4 px late: positions 0, 2, 4.4, 6, …
    table = [2.0 * k + (0.4 if k == 2 else 0.0) for k in range(8)]
    cal = cassi.calibrate(y, mask, bands=8, band_spread=POINT, blur_pass=False, band_offsets=table)
    held = cal.band_offsets
    assert len(held) == 8 and held[0] == 0.0 and held[2] > 0.3, held
    assert json.loads(cal.to_json())["band_offsets"]["offsets"] == held
    assert cassi.calibrate(y, mask, bands=8, band_spread=POINT, blur_pass=False).band_offsets is None
    # the reconstruction holds the calibration's table: not the same
    # parameters without it
    with_table = cassi.reconstruct(y, mask, bands=8, calibration=cal, iterations=3)
    without = cassi.reconstruct(y, mask, bands=8, mismatch=cal.reconstruction_parameters,
                                model=cal.model, iterations=3)
    assert not np.array_equal(with_table, without)
    # so does an Operator of the calibration
    x = scene.astype(np.float32)
    held_op = cassi.Operator(mask, bands=8, mismatch=cal)
    plain_op = cassi.Operator(mask, bands=8, mismatch=cal.reconstruction_parameters, model=cal.model)
    assert not np.array_equal(held_op.forward(x), plain_op.forward(x))
    with pytest.raises(ValueError, match="band_offsets: 3 values, expected 8"):
        cassi.calibrate(y, mask, bands=8, band_spread=POINT, band_offsets=[0.0, 2.0, 4.0])
    with pytest.raises(ValueError, match="band_offsets.*paper preset"):
        cassi.calibrate(y, mask, bands=8, preset="paper", band_offsets=table)
    with pytest.raises(ValueError, match="wavelengths"):
        cassi.calibrate(y, mask, bands=8, band_spread=POINT, band_offsets=[450.0 + 7.0 * k for k in range(8)])


def test_a_band_spread_is_kept_and_travels_to_the_reconstruction(case):
    scene, mask, _ = case
    y = cassi.simulate_physical(scene, mask, TRUTH, oversample=2, band_spread="uniform",
                                noise=False)
    cal = cassi.calibrate(y, mask, bands=8, blur_pass=False, band_spread="uniform")
    assert cal.band_spread == "uniform"
    assert json.loads(cal.to_json())["band_spread"] == "uniform"
    plain = cassi.calibrate(y, mask, bands=8, blur_pass=False, band_spread=POINT)
    assert plain.band_spread == "point" and "band_spread" not in json.loads(plain.to_json())
    # the default: spread evenly with the dispersed-mask model (a camera's
    # continuous spectrum), a point with the rounded model
    assert cassi.calibrate(y, mask, bands=8, blur_pass=False).band_spread == "uniform"
    assert cassi.calibrate(y, mask, bands=8, model="rounded").band_spread == "point"
    # the reconstruction and an Operator of the calibration spread the bands too
    spread = cassi.reconstruct(y, mask, bands=8, calibration=cal, iterations=3)
    without = cassi.reconstruct(y, mask, bands=8, mismatch=cal.reconstruction_parameters,
                                model=cal.model, iterations=3)
    assert not np.array_equal(spread, without)
    x = scene.astype(np.float32)
    spread_op = cassi.Operator(mask, bands=8, mismatch=cal)
    point_op = cassi.Operator(mask, bands=8, mismatch=cal.reconstruction_parameters,
                              model=cal.model)
    assert not np.array_equal(spread_op.forward(x), point_op.forward(x))
    with pytest.raises(ValueError, match="band_spread.*'box'"):
        cassi.calibrate(y, mask, bands=8, band_spread="box")
    with pytest.raises(ValueError, match="band_spread.*paper preset"):
        cassi.calibrate(y, mask, bands=8, preset="paper", band_spread="linear")


def test_calibrated_reconstruction_beats_the_nominal_model(case):
    scene, mask, y = case
    cal = cassi.calibrate(y, mask, bands=8, model="rounded")
    assumed = cassi.reconstruct(y, mask, bands=8)
    corrected = cassi.reconstruct(y, mask, bands=8, calibration=cal)
    oracle = cassi.reconstruct(y, mask, bands=8, mismatch=TRUTH)
    score = {k: cassi.metrics(scene, np.clip(c, 0, 1))["psnr"]
             for k, c in [("assumed", assumed), ("corrected", corrected), ("oracle", oracle)]}
    assert score["corrected"] > score["assumed"] + 3, score
    assert score["corrected"] > score["oracle"] - 1.0, score
    with pytest.raises(ValueError, match="not both"):
        cassi.reconstruct(y, mask, bands=8, calibration=cal, dx=1.0)
    with pytest.raises(ValueError, match="differs from the calibration's model"):
        cassi.reconstruct(y, mask, bands=8, calibration=cal, model="subpixel")
    # an Operator of the calibration takes its model too, never silently another
    op = cassi.Operator(mask, bands=8, mismatch=cal)
    assert (op.model, op.mismatch) == (cal.model, cal.reconstruction_parameters)
    with pytest.raises(ValueError, match="differs from the calibration's model 'rounded'"):
        cassi.Operator(mask, bands=8, mismatch=cal, model="subpixel")


def test_metrics_are_the_library_definitions(rng):
    truth = rng.random((4, 16, 16), dtype=np.float32)
    noisy = truth + np.float32(0.1)
    m = cassi.metrics(truth, noisy)
    assert m["psnr"] == pytest.approx(20.0, abs=1e-4)  # MSE 0.01, peak 1
    assert cassi.metrics(truth, truth)["psnr"] == float("inf")
    assert cassi.metrics(truth, 2 * truth)["sam_deg"] == pytest.approx(0.0, abs=1e-3)
    assert 0 < m["ssim"] < 1 and set(m) == {"psnr", "psnr_band_mean", "ssim", "sam_deg"}
    assert "SSIM" in cassi.METRIC_DEFINITIONS
    with pytest.raises(ValueError, match="shape"):
        cassi.metrics(truth, truth[:3])


def test_reconstruction_progress_and_info(case):
    _, mask, y = case
    seen = []
    cube, info = cassi.reconstruct(y, mask, bands=8, iterations=7, progress=seen.append, return_info=True)
    assert [s["iteration"] for s in seen] == list(range(1, 8))
    assert all(s["max_iterations"] == 7 for s in seen)
    assert info["iterations"] == 7 and info["method"] == "gap-tv" and cube.dtype == np.float32
    for method in cassi.ITERATIVE_METHODS:
        assert cassi.reconstruct(y, mask, bands=8, method=method, iterations=3).shape == (8, 96, 96)


def test_an_error_in_the_progress_callback_stops_the_work(case):
    _, mask, y = case
    calls = []

    def boom(info):
        calls.append(info)
        raise RuntimeError("stop here")

    with pytest.raises(RuntimeError, match="stop here"):
        cassi.reconstruct(y, mask, bands=8, iterations=50, progress=boom)
    assert len(calls) == 1
    with pytest.raises(RuntimeError, match="stop here"):
        cassi.calibrate(y, mask, bands=8, model="rounded", progress=boom)


def _count_for(seconds, work=None):
    """How far a Python thread counts while `work` runs (or for `seconds`)."""
    stop = threading.Event()
    n = [0]

    def count():
        while not stop.is_set():
            n[0] += 1

    t = threading.Thread(target=count)
    t.start()
    started = time.perf_counter()
    if work:
        work()
    else:
        time.sleep(seconds)
    elapsed = time.perf_counter() - started
    stop.set()
    t.join()
    return n[0] / elapsed


def test_the_gil_is_released_while_the_library_works(case):
    _, mask, y = case
    alone = _count_for(0.3)
    during = _count_for(None, lambda: cassi.reconstruct(y, mask, bands=8, iterations=150))
    # holding the GIL would stop the counter almost completely; 2 cores are
    # shared with the solver's threads
    assert during > 0.1 * alone, (during, alone)
