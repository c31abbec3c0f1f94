"""bench/efficiency_vs_cycles.py's arithmetic and report, on synthetic images
and rows (no Blender, no renders): the error, the reference-noise
correction, the efficiency ratio, time per sample, the CSV round trip, the
Auto-rule table and the regenerated report keeping its hand-written notes."""
import importlib.util
import math
import sys
from pathlib import Path

import numpy as np
import pytest

REPO = Path(__file__).resolve().parents[2]


def load(name):
    sys.path.insert(0, str(REPO / "bench"))
    spec = importlib.util.spec_from_file_location(name, REPO / "bench" / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


bench = load("efficiency_vs_cycles")
report = load("efficiency_report")


def test_mse_is_over_rgb_only():
    ref = np.zeros((4, 5, 4))
    img = np.full((4, 5, 4), 0.1)
    img[..., 3] = 7.0  # alpha differs a lot and must not count
    img[0, 0, 0] = 0.5  # one channel of one pixel: (0.5^2 + 59 * 0.1^2) / 60
    assert bench.mse(img, ref) == pytest.approx((0.25 + 59 * 0.01) / 60, rel=1e-12)


def test_mse_rejects_a_size_mismatch():
    with pytest.raises(ValueError, match="shape"):
        bench.mse(np.zeros((4, 4, 3)), np.zeros((4, 5, 3)))


def test_reference_noise_is_subtracted():
    """Truth plus known noise: the halves' difference gives the reference's
    variance, and subtracting it recovers a test image's own noise."""
    rng = np.random.default_rng(7)
    truth = rng.uniform(0.0, 2.0, (256, 256, 3))
    sigma_ref_half, sigma_img = 0.05, 0.03
    half_a = truth + rng.normal(0, sigma_ref_half, truth.shape)
    half_b = truth + rng.normal(0, sigma_ref_half, truth.shape)
    reference, ref_var = bench.reference_from_halves(half_a, half_b)
    assert ref_var == pytest.approx(sigma_ref_half ** 2 / 2, rel=0.03)
    image = truth + rng.normal(0, sigma_img, truth.shape)
    raw = bench.mse(image, reference)
    assert raw == pytest.approx(sigma_img ** 2 + sigma_ref_half ** 2 / 2, rel=0.03)
    assert bench.corrected_mse(raw, ref_var) == pytest.approx(sigma_img ** 2, rel=0.05)
    assert bench.corrected_mse(1.0, 5.0) == pytest.approx(0.01)  # floored, never zero or negative


def row(scene, engine, sampler, pattern, spp, seconds, mse, rep=1):
    return dict(scene=scene, engine=engine, sampler=sampler, pattern=pattern, spp=spp, rep=rep, seconds=seconds,
                mse_vs_reference=mse, reference_variance=0.0, mse=mse)


def test_efficiency_ratio_averages_repetitions():
    rows = [row("s", "cycles", "-", "-", 64, 2.0, 4e-4),
            row("s", "coherent", "auto", "white", 64, 3.0, 1e-4, rep=1),
            row("s", "coherent", "auto", "white", 64, 5.0, 3e-4, rep=2)]
    s = report.summarise(rows)
    ours = s[("s", "coherent", "auto", "white", 64)]
    assert (ours["mse"], ours["seconds"], ours["n"]) == (pytest.approx(2e-4), pytest.approx(4.0), 2)
    assert report.efficiency_ratio(s[("s", "cycles", "-", "-", 64)], ours) == pytest.approx(1.0)
    assert report.efficiency(ours) == pytest.approx(1 / 8e-4)


def test_time_per_sample_recovers_a_line():
    setup, per_sample = report.time_per_sample([(n, 0.5 + 0.01 * n) for n in (16, 64, 256, 1024)])
    assert (setup, per_sample) == (pytest.approx(0.5), pytest.approx(0.01))
    assert math.isnan(report.time_per_sample([(16, 1.0)])[1])


def synthetic_rows():
    """Two scenes; at 16 spp ICPT is the most efficient sampler, at 256 CPT.
    Auto renders ICPT's image at 16 spp and CPT's at 256."""
    rows = []
    for scene, scale in (("a", 1.0), ("b", 3.0)):
        for spp in (16, 256):
            rows.append(row(scene, "cycles", "-", "-", spp, 0.01 * spp, scale * 0.1 / spp))
            best = "icpt" if spp == 16 else "cpt"
            for sampler in ("spt", "cpt", "icpt"):
                mse = scale * (0.1 if sampler == best else 0.2) / spp
                rows.append(row(scene, "coherent", sampler, "white", spp, 0.02 * spp, mse))
                if sampler == best:
                    rows.append(row(scene, "coherent", "auto", "white", spp, 0.021 * spp, mse))
    return rows


def test_csv_round_trip(tmp_path):
    rows = synthetic_rows()
    bench.write_csv(tmp_path / "r.csv", rows)
    back = bench.read_csv(tmp_path / "r.csv")
    assert back == rows
    assert isinstance(back[0]["spp"], int) and isinstance(back[0]["mse"], float)


def test_auto_rule_table_names_best_and_auto():
    rep = report.Report(synthetic_rows(), {})
    rules = {r["spp"]: r for r in report.rule_numbers(rep)}
    assert (rules[16]["best"], rules[16]["auto"], rules[16]["wins"]["icpt"]) == ("icpt", "icpt", 2)
    assert (rules[256]["best"], rules[256]["auto"]) == ("cpt", "cpt")
    assert rules[256]["relative"]["spt"] == pytest.approx(0.5)  # half the efficiency of the best


def test_report_regenerates_and_keeps_notes(tmp_path):
    rows = synthetic_rows()
    info = dict(commands=["/usr/bin/python3 bench/efficiency_vs_cycles.py --test"], defaults=dict(pattern="white"))
    report.write(tmp_path, rows, info)
    md = (tmp_path / "efficiency_vs_cycles.md").read_text()
    assert (tmp_path / "efficiency_vs_cycles.png").stat().st_size > 0
    assert "--test" in md
    # Scene a, 16 spp: Cycles MSE x s = 0.1/16 x 0.16; Auto's = 0.1/16 x 0.336: ratio 0.48.
    assert "| a | 16 | " in md and "**0.48**" in md
    path = tmp_path / "efficiency_vs_cycles.md"
    path.write_text(md.replace("(none yet)", "Hand-written analysis."))
    report.write(tmp_path, rows, info)
    assert "Hand-written analysis." in path.read_text()
