"""Design: flip graph, exact search = brute force, search model = analyser, shipped designs."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from click.testing import CliRunner
from realdata import REPO

from calib.analysis.mounting import analyze
from calib.analysis.worst_case import analyze_tolerance
from calib.model import params as P
from calib.model.requirements import PAPER
from calib.nav.site import Site
from calib.nav.transform import attitude_from_directions, rot_axis
from calib.noise.profiles import load_profile
from calib.sequence.definition import load_sequence
from seqdesign.cli import main
from seqdesign.search import Constraints, Move, SearchModel, beam_search, brute_force, flip_graph, to_sequence

LAT = math.radians(40.0)
SITE = Site.at(LAT)
ADIS = REPO / "benchmarks" / "profiles" / "adis16405.toml"
PROFILE = load_profile("navigation")


def test_flip_graph_has_the_24_grid_attitudes_and_follows_the_flip_rule():
    g = flip_graph(("east", "up", "south"))
    assert g.number_of_nodes() == 24  # the rotation group of the cube
    for node in g.nodes:
        out = list(g.out_edges(node, data=True))
        assert sorted((d["axis"], d["sign"]) for _, _, d in out) == sorted(
            (a, s) for a in "XYZ" for s in (1, -1)
        )
        C = attitude_from_directions(*node)
        for _, nxt, d in out:
            expected = C @ rot_axis("XYZ".index(d["axis"]), d["sign"] * math.pi / 2)
            assert np.allclose(attitude_from_directions(*nxt), expected, atol=1e-12)


@pytest.fixture(scope="module")
def small_model():
    c = Constraints(budget_s=600.0, max_flips=2, max_quarters=2, min_dwell_s=30, max_dwell_s=300)
    return SearchModel.build(c, 120.0, SITE, PROFILE)


@pytest.mark.parametrize("objective", ["worst", "A", "D", "E"])
def test_exhaustive_search_returns_the_brute_force_optimum(small_model, objective):
    finals, n = beam_search(small_model, objective, beam_width=None, keep=1)
    best = brute_force(small_model, 2, objective)
    assert finals[0].walk == best.walk
    assert finals[0].score == pytest.approx(best.score, rel=1e-12)
    assert n == 12 + 12 * 12  # every walk of one and two moves, each scored once


def test_search_model_agrees_with_the_exact_analyser():
    # The search scores a walk with segment matrices (rest-steady filter covariance at
    # each segment start, 0.5 s intervals in turns, 12 per rest); the exact analyser
    # runs the whole sequence. 2 % is far below the gaps between designs it ranks.
    paper = load_sequence("paper-9pos")
    c = Constraints(budget_s=1800.0, max_flips=8, max_quarters=1)
    model = SearchModel.build(c, 180.0, SITE, PROFILE)
    cand = model.start_candidate()
    for s in paper.steps:
        mv = Move(s.axis, 1 if s.angle_deg > 0 else -1, 1)
        cand = next(k for k in model.extend([cand], "worst") if k.walk[-1] == mv)
    exact = analyze(paper, PROFILE, SITE).worst[1]
    assert cand.score == pytest.approx(exact, rel=0.02)


def test_dask_local_cluster_gives_the_serial_result():
    distributed = pytest.importorskip("dask.distributed")
    from seqdesign.search.beam import BeamJob, search_at_dwell
    from seqdesign.search.parallel import map_jobs

    c = Constraints(budget_s=400.0, max_flips=2, max_quarters=1)
    jobs = [BeamJob(c, d, SITE, PROFILE, "worst", 20, 2, PAPER) for d in (60.0, 90.0)]
    serial = map_jobs(search_at_dwell, jobs)
    with (
        distributed.LocalCluster(
            # ":0": a free port; two clusters in two test workers both asked for dask's 8787, and
            # the loser's fallback left its first socket open (a ResourceWarning, an error here)
            n_workers=2,
            threads_per_worker=1,
            processes=True,
            dashboard_address=":0",
        ) as cluster,
        distributed.Client(cluster) as client,
    ):
        remote = map_jobs(search_at_dwell, jobs, scheduler=client)
    for a, b in zip(serial, remote, strict=True):
        assert a.dwell_s == b.dwell_s and a.evaluated == b.evaluated
        assert a.walks == b.walks
        assert a.scores == b.scores  # bit-identical scores


def test_local_workers_give_the_serial_result():
    from seqdesign.search.beam import BeamJob, search_at_dwell
    from seqdesign.search.parallel import map_jobs, worker_pool

    c = Constraints(budget_s=400.0, max_flips=2, max_quarters=1)
    jobs = [BeamJob(c, d, SITE, PROFILE, "worst", 20, 2, PAPER) for d in (60.0, 90.0)]
    serial = map_jobs(search_at_dwell, jobs)
    parallel = map_jobs(search_at_dwell, jobs, workers=2)
    # the pool a design keeps for all its rounds: the same workers twice, the same answer
    with worker_pool(2):
        kept = [map_jobs(search_at_dwell, jobs, workers=2), map_jobs(search_at_dwell, jobs[::-1], workers=2)]

    def figures(results):
        return [(r.dwell_s, r.walks, r.scores, r.evaluated) for r in results]

    assert figures(serial) == figures(parallel) == figures(kept[0]) == figures(kept[1][::-1])


@pytest.mark.parametrize(
    "name,budget_s,target", [("designed-15min", 900.0, 1.9), ("designed-30min", 1800.0, 1.35)]
)
def test_shipped_designs_beat_the_paper_and_meet_the_targets(name, budget_s, target):
    """Issue targets: worst ratio <= 1.9 within 15 min, <= 1.35 within 30 min (navigation
    profile, latitude 40 deg, worst case over +-3 deg), each better than paper-9pos."""
    seq = load_sequence(name)
    assert seq.duration_s <= budget_s + 1e-6
    rob = analyze_tolerance(seq, PROFILE, SITE, 3.0)
    worst = rob.per_parameter_worst_ratio.max()
    paper = analyze_tolerance(load_sequence("paper-9pos"), PROFILE, SITE, 3.0, search=False)
    assert worst <= target
    assert worst < paper.per_parameter_worst_ratio.max()
    assert rob.worst.rank == 21


def test_to_sequence_round_trips_a_walk(tmp_path):
    from calib.sequence.definition import save_sequence

    c = Constraints()
    walk = (Move("X", -1, 4), Move("Z", 1, 5))
    seq = to_sequence(walk, c, [60.0, 70.0, 80.0], "w")
    save_sequence(seq, tmp_path / "w.toml")
    back = load_sequence(tmp_path / "w.toml")
    assert [s.angle_deg for s in back.steps] == [-360.0, 450.0]
    assert back.initial_dwell_s == 60.0 and [s.dwell_s for s in back.steps] == [70.0, 80.0]


@pytest.mark.parametrize(
    "args,needle",
    [
        (["--axes", "W"], "--axes"),
        (["--budget-min", "-1"], "budget"),
        (["--start", "east,east,up"], "--start"),
        (["--max-flips", "0"], "--max-flips"),
    ],
)
def test_cli_design_refuses_bad_constraints(args, needle, tmp_path):
    r = CliRunner().invoke(main, ["design", "-o", str(tmp_path / "x.toml")] + args)
    assert r.exit_code != 0 and needle in r.output and "Traceback" not in r.output
    assert not (tmp_path / "x.toml").exists()


def test_cli_design_small_end_to_end(tmp_path):
    out = tmp_path / "d.toml"
    r = CliRunner().invoke(
        main,
        [
            "design",
            "--budget-min",
            "8",
            "--max-flips",
            "3",
            "--max-quarters",
            "1",
            "--beam-width",
            "20",
            "--no-refine",
            "--tolerance-deg",
            "0",
            "-o",
            str(out),
            "--json",
        ],
    )
    assert r.exit_code == 0, r.output
    doc = json.loads(r.stdout)
    seq = load_sequence(out)
    assert seq.duration_s <= 8 * 60 + 1e-6
    assert seq.provenance["objective"] == "worst" and "command" in seq.provenance
    # --no-refine keeps the search's uniform dwells; the site it was designed for is recorded.
    assert {s.dwell_s for s in seq.steps} == {seq.initial_dwell_s}
    assert seq.latitude_deg == 40.0 and seq.height_m == 0.0
    # The file's recorded score is the analyser's figure for the file's own sequence.
    exact = analyze(seq, PROFILE, SITE).ratio.max()
    assert doc["designs"][0]["worst"]["ratio"] == pytest.approx(exact, rel=1e-9)


# ---------------------------------------------------------------------------
# Issue 12: any profile, --with terms, a bigger space, never a worse answer

GM = load_profile("navigation-gm")


def _fold_walk(model, seq):
    """The search model's score of a shipped sequence's walk (uniform dwells)."""
    cand = model.start_candidate()
    for s in seq.steps:
        mv = Move(s.axis, 1 if s.angle_deg > 0 else -1, int(round(abs(s.angle_deg) / 90)))
        cand = next(k for k in model.extend([cand], "worst") if k.walk[-1] == mv)
    return cand.score


@pytest.mark.slow
def test_gm_search_score_equals_the_analyser():
    # Under Gauss-Markov bias instability each candidate carries its own noise-filter
    # covariance, so the search whitens as analyze does; what remains is the interval
    # pattern (12 per rest against 5 s; 1 s in turns against 0.5 s), worth < 1 % (issue 12).
    seq = load_sequence("paper-9pos")  # uniform 180 s dwells: the search's own model
    c = Constraints(budget_s=1800.0, max_flips=9, max_quarters=1)
    model = SearchModel.build(c, seq.steps[0].dwell_s, SITE, GM)
    exact = analyze_tolerance(seq, GM, SITE, 0.0).per_parameter_worst_ratio.max()
    assert _fold_walk(model, seq) == pytest.approx(exact, rel=0.01)


def test_gm_exhaustive_search_returns_the_brute_force_optimum():
    c = Constraints(budget_s=400.0, max_flips=2, max_quarters=1, axes="XY")
    model = SearchModel.build(c, 90.0, SITE, GM)
    finals, n = beam_search(model, "worst", beam_width=None, keep=1)
    best = brute_force(model, 2, "worst")
    assert finals[0].walk == best.walk
    assert finals[0].score == pytest.approx(best.score, rel=1e-12)


def test_sigma_gradient_matches_finite_differences():
    # The worst-mounting search's exact gradient (SO(3) left Jacobian through the 63-term
    # basis) against central differences of the analyser's own sigma. Step 1e-5 rad:
    # truncation h^2 sigma'''/6 ~ 1e-10 of sigma, ~1e-6 of the largest gradient component;
    # tolerance 1e-5 of that component.
    from calib.analysis.mounting import sequence_model

    model = sequence_model(load_sequence("paper-9pos"), PROFILE, SITE)
    theta = np.radians([1.0, -2.0, 2.5])
    for index in (5, 17):  # sgz, saz
        sigma, grad = model.sigma_gradient(theta, index)
        assert sigma == pytest.approx(model.analyze(theta).sigma[index], rel=1e-9)
        h = 1e-5
        fd = [
            (model.analyze(theta + h * e).sigma[index] - model.analyze(theta - h * e).sigma[index]) / (2 * h)
            for e in np.eye(3)
        ]
        assert np.allclose(grad, fd, rtol=1e-5, atol=1e-5 * np.abs(fd).max())
    # and at the nominal mounting, where the closed form switches to its series
    sigma, grad = model.sigma_gradient(np.zeros(3), 5)
    fd = [(model.analyze(h * e).sigma[5] - model.analyze(-h * e).sigma[5]) / (2 * h) for e in np.eye(3)]
    assert np.allclose(grad, fd, rtol=1e-5, atol=1e-5 * np.abs(fd).max())


@pytest.mark.slow
def test_design_with_terms_scores_the_21_with_them_fitted():
    from calib.analysis.worst_case import analyze_extras
    from calib.model.optional_terms import OptionalTerms
    from seqdesign.search import DesignOptions, design

    c = Constraints(budget_s=360.0, max_flips=3, max_quarters=2, min_dwell_s=10.0)
    ext = OptionalTerms(("lever-arm",))
    options = DesignOptions(latitude_deg=40.0, tolerance_deg=1.0, beam_width=10, refine=False, extras=ext)
    res = design(c, PROFILE, options, keep=1)
    cost = analyze_extras(res.sequence, PROFILE, SITE, ext, 1.0, search=True)
    # the objective is the worst 3 sigma/requirement of the 21 with the lever arms fitted,
    # as `analyze --with` reports it (same 27 box points and the same IPOPT search inside
    # the box, same arithmetic: equal to rounding)
    assert res.worst_ratio == pytest.approx(PAPER.ratio(cost.sigma_with).max(), rel=1e-9)
    assert res.extras_cost is not None and len(res.extras_cost.extra_sigma) == 9
    assert len(res.extras_cost.verdicts()) == 9


@pytest.mark.slow
def test_more_effort_never_gives_a_worse_answer():
    # Issue 12 point 6: the answer is the best exactly re-scored candidate seen, and the
    # default beam runs a narrow beam too, so it cannot lose to --beam-width 20 or to
    # --no-refine. A 5-min budget with 3 single quarter turns keeps this short.
    from seqdesign.search import DesignOptions, design

    c = Constraints(budget_s=300.0, max_flips=3, max_quarters=1, min_dwell_s=10.0)
    default = design(c, PROFILE, DesignOptions(beam_width=60), keep=1)
    narrow = design(c, PROFILE, DesignOptions(beam_width=20), keep=1)
    unrefined = design(c, PROFILE, DesignOptions(beam_width=60, refine=False), keep=1)
    assert default.worst_ratio <= narrow.worst_ratio + 1e-12
    assert default.worst_ratio <= unrefined.worst_ratio + 1e-12


@pytest.mark.slow
def test_whole_design_on_two_workers_equals_the_serial_one():
    # The beams and the exact re-scoring of the candidates run on the workers; the same
    # arithmetic in another process must give the same walk, dwells and figures, bit for bit.
    # (Two workers may re-score a candidate the serial run skips as unable to win, so the
    # list of finalists may be longer; its best is the same.)
    from seqdesign.search import DesignOptions, design

    c = Constraints(budget_s=300.0, max_flips=3, max_quarters=1, min_dwell_s=10.0)
    serial = design(c, PROFILE, DesignOptions(beam_width=30), keep=1)
    parallel = design(c, PROFILE, DesignOptions(beam_width=30, workers=2), keep=1)
    assert serial.sequence.steps == parallel.sequence.steps
    assert serial.finalists[0] == parallel.finalists[0]
    assert set(serial.finalists) <= set(parallel.finalists)
    assert (serial.worst_ratio, serial.worst_name) == (parallel.worst_ratio, parallel.worst_name)
    assert serial.uniform_worst_ratio == parallel.uniform_worst_ratio


@pytest.mark.slow
def test_whole_design_on_a_dask_cluster_equals_the_serial_one():
    # The exact re-scoring goes to the cluster too (a picklable ExactScorer through
    # client.map): same walk, dwells and figures as the serial run, bit for bit.
    distributed = pytest.importorskip("dask.distributed")
    from seqdesign.search import DesignOptions, design

    c = Constraints(budget_s=300.0, max_flips=3, max_quarters=1, min_dwell_s=10.0)
    serial = design(c, PROFILE, DesignOptions(beam_width=30), keep=1)
    with (
        distributed.LocalCluster(
            # ":0": a free port; two clusters in two test workers both asked for dask's 8787, and
            # the loser's fallback left its first socket open (a ResourceWarning, an error here)
            n_workers=2,
            threads_per_worker=1,
            processes=True,
            dashboard_address=":0",
        ) as cluster,
        distributed.Client(cluster) as client,
    ):
        remote = design(c, PROFILE, DesignOptions(beam_width=30, scheduler=client), keep=1)
    assert serial.sequence.steps == remote.sequence.steps
    assert (serial.worst_ratio, serial.worst_name) == (remote.worst_ratio, remote.worst_name)
    assert serial.finalists[0] == remote.finalists[0]


def test_motif_repetitions_fill_the_budget_with_short_dwells():
    from seqdesign.search.pipeline import motif_dwell

    c = Constraints(budget_s=1800.0, min_dwell_s=10.0)
    walk = (Move("X", 1, 4), Move("Y", -1, 5))  # 81 s of turning per play
    d = motif_dwell(walk, c, 3)
    assert 3 * 81.0 + 7 * d <= 1800.0 + 1e-9 and d > 1800.0 / 7 - 81.0 * 3 / 7 - 0.1
    assert motif_dwell(walk, Constraints(budget_s=300.0, min_dwell_s=30.0), 3) is None


def test_cli_design_refuses_unknown_terms(tmp_path):
    r = CliRunner().invoke(main, ["design", "--with", "magnetometer", "-o", str(tmp_path / "x.toml")])
    assert r.exit_code == 2 and "--with" in r.output and "Traceback" not in r.output
    assert not (tmp_path / "x.toml").exists()


@pytest.mark.slow
@pytest.mark.parametrize(
    "name,budget_s,limit", [("designed-15min-gm", 900.0, 1.95), ("designed-30min-gm", 1800.0, 1.40)]
)
def test_shipped_gm_designs_beat_the_white_noise_designs_on_the_real_unit(name, budget_s, limit):
    """Issue 12's targets: under navigation-gm with every extra term fitted (latitude 40 deg,
    worst over +-3 deg), <= 1.95 within 15 min and <= 1.40 within 30 min (the white-noise
    designs the issue measured, 9 moves each, reached 2.53 and 2.26 there)."""
    from calib.analysis.worst_case import analyze_extras
    from calib.model.optional_terms import GROUP_NAMES, OptionalTerms

    seq = load_sequence(name)
    assert seq.duration_s <= budget_s + 1e-6
    cost = analyze_extras(seq, GM, SITE, OptionalTerms(GROUP_NAMES), 3.0)
    assert PAPER.ratio(cost.sigma_with).max() <= limit
    assert all(v == "observable" for v in cost.verdicts())


def test_dwell_groups_tie_motif_plays_and_block_long_motifs():
    from seqdesign.search.refine import MAX_REFINE_DWELLS, dwell_groups

    g = dwell_groups(18, 3)  # a 6-move motif played 3 times: one variable per motif move
    assert list(g[:1]) == [0] and list(g[1:7]) == list(range(1, 7))
    assert list(g[7:13]) == list(g[1:7]) == list(g[13:19])
    g = dwell_groups(33)  # one long walk: contiguous blocks, each used, in order
    assert g.max() == MAX_REFINE_DWELLS and np.all(np.diff(g[1:]) >= 0)
    assert set(g[1:]) == set(range(1, MAX_REFINE_DWELLS + 1))


def test_default_space_holds_many_short_moves():
    # Issue 12: at least 30 moves and dwells down to 10 s in the beam itself.
    from seqdesign.search.design import search_dwells

    c = Constraints(budget_s=1800.0)
    assert c.max_flips >= 30 and min(search_dwells(c)) <= 10.0
    assert max(search_dwells(c)) >= 100.0  # and the few-moves, long-dwell space still
    # 30 moves of 450 deg (45 s each) and 31 dwells of 10 s fit 30 min: the beam can reach them
    assert 30 * 45.0 + 31 * 10.0 <= c.budget_s


@pytest.mark.parametrize("batch", [1, 2, 5])
def test_pruned_rescoring_finds_the_brute_force_best(batch):
    # Entries carry a lower bound of their score (the nominal mounting is a point of the
    # box; the search inside the box only raises the box figure). Skipping those whose
    # bound is not below the best score so far must still return the overall best.
    from dataclasses import dataclass

    from seqdesign.search.pipeline import pruned

    @dataclass(frozen=True)
    class Entry:  # a finalist: its lower bound, its label, and the score it will get
        ratio: float
        label: str
        score: float

    @dataclass(frozen=True)
    class Score:
        ratio: float

    rng = np.random.default_rng(7)
    for _ in range(200):
        n = int(rng.integers(1, 12))
        bounds = np.round(rng.uniform(1.0, 2.0, n), 2)  # rounded: ties happen
        scores = bounds + np.round(rng.exponential(0.2, n), 2)
        entries = sorted(
            (
                Entry(float(b), f"walk{i}", float(s))
                for i, (b, s) in enumerate(zip(bounds, scores, strict=True))
            ),
            key=lambda f: (f.ratio, f.label, f.score),
        )
        best, scored = pruned(entries, lambda fs: [Score(f.score) for f in fs], batch)
        brute = min(entries, key=lambda f: (f.score, f.label))
        assert best.finalist == brute and best.exact.ratio == brute.score
        assert len(scored) <= n


def test_refinement_jacobian_is_the_derivative_of_the_ratios():
    # The callback's batched central differences against a function whose derivative is
    # known in closed form: r_i(x) = sum_j a_ij (scale x_j)^2 / 2, dr_i/dx_j = a_ij scale^2 x_j.
    # Quadratic, so central differences are exact up to rounding (~1e-16 / 1e-4 relative).
    import casadi as ca

    from seqdesign.search.refine import _ratios_callback

    n, scale = 4, 100.0
    a = np.random.default_rng(3).uniform(0.5, 2.0, (P.N_PARAMS, n))

    def ratios_many(D):
        return 0.5 * np.asarray(D) ** 2 @ a.T

    cb = _ratios_callback(ratios_many, n, scale)
    x = ca.MX.sym("x", n)
    jac = ca.Function("dratios", [x], [ca.jacobian(cb(x), x)])
    x0 = np.array([0.1, 0.2, 0.3, 0.4])
    assert np.allclose(np.asarray(jac(x0)), a * scale**2 * x0, rtol=1e-9)
    assert np.allclose(np.asarray(cb(x0)).ravel(), ratios_many((x0 * scale)[None])[0])


def test_batched_walk_information_equals_one_walk_at_a_time():
    # The GM refinement folds all finite-difference points at once; each row must be the
    # information of that dwell set alone (same arithmetic, batched: equal to rounding).
    from seqdesign.search.refine import _walk_information_exact, walk_informations_exact

    prof = load_profile("navigation-gm")
    c = Constraints(budget_s=600.0, min_dwell_s=10.0)
    walk = (Move("Z", 1, 5), Move("Y", 1, 5), Move("X", -1, 5))
    D = np.array([[10.0, 12.0, 15.0, 11.0], [30.0, 10.0, 10.0, 25.0], [10.0] * 4])
    batched = walk_informations_exact(walk, c, D, SITE, prof)
    for d, N in zip(D, batched, strict=True):
        single = _walk_information_exact(walk, c, list(d), SITE, prof)
        assert np.allclose(N, single, rtol=1e-12, atol=1e-12 * np.abs(single).max())


@pytest.mark.parametrize("name", ["navigation-gm", str(ADIS)])
def test_refinement_turns_in_closed_form_equal_the_interval_fold(name):
    # The refinement folds each turn through its segment block (Woodbury, built once)
    # instead of the Kalman loop over its intervals: the same information, variances to 1e-10.
    from calib.model.information import inverse_diagonal
    from seqdesign.search.refine import walk_informations_exact

    prof = load_profile(name)
    c = Constraints(budget_s=600.0, min_dwell_s=10.0)
    walk = (Move("Z", 1, 5), Move("Y", 1, 5), Move("X", -1, 5), Move("Z", -1, 2), Move("Y", 1, 3))
    D = np.array([[10.0, 12.0, 15.0, 11.0, 40.0, 20.0], [30.0, 10.0, 10.0, 25.0, 10.0, 100.0]])
    fast = walk_informations_exact(walk, c, D, SITE, prof)
    ref = walk_informations_exact(walk, c, D, SITE, prof, closed_form=False)
    for a, b in zip(fast, ref, strict=True):
        d = np.sqrt(np.diag(b))
        assert np.max(np.abs(a - b) / np.outer(d, d)) < 1e-10
        # the 21's variances (the ratios'); phi0's heading under a MEMS gyro, 1 rad^2, to 2e-10
        np.testing.assert_allclose(inverse_diagonal(a)[:21], inverse_diagonal(b)[:21], rtol=1e-10)


@pytest.mark.slow
def test_cli_pareto_front_writes_both_bounds_for_a_gauss_markov_profile(tmp_path):
    # The front's CSV carries the white-noise bound of the conventions and the coloured-noise
    # bound at the gimbal's rate: VRW only, sqrt(3/T) VRW/g, and with the GM density at one
    # turn per 360/rate s added to VRW^2 (derived here from the profile, not the code).
    stem = tmp_path / "front"
    r = CliRunner().invoke(
        main,
        [
            "design",
            "--pareto",
            "--budgets",
            "4,6",
            "--max-flips",
            "3",
            "--max-quarters",
            "1",
            "--beam-width",
            "10",
            "--no-refine",
            "--tolerance-deg",
            "0",
            "--profile",
            "navigation-gm",
            "-o",
            str(stem),
        ],
    )
    assert r.exit_code == 0, r.output
    lines = (tmp_path / "front.csv").read_text().splitlines()
    assert lines[0] == "budget_min,duration_s,worst_ratio,worst_parameter,bound_ratio,rate_bound_ratio"
    s2 = math.sin(LAT) ** 2  # WGS-84 normal gravity at sea level (Somigliana, conventions.md)
    g = 9.7803253359 * (1 + 0.00193185265241 * s2) / math.sqrt(1 - 0.00669437999013 * s2)
    tau, sigma = GM.accel_bias_correlation_s, GM.accel_gm_sigma
    omega = math.radians(10.0)  # the default rate, rad/s
    density = GM.vrw**2 + 2 * sigma**2 * tau / (1 + (omega * tau) ** 2)
    for line in lines[1:3]:
        _, T, worst, _, bound, rate_bound = line.split(",")
        T = float(T)
        white = 3 * GM.vrw * math.sqrt(3 / T) / g / (1e-6 * 1.0)  # requirement 1 ppm
        assert float(bound) == pytest.approx(white, rel=1e-4)  # the CSV's 4 decimals
        assert float(rate_bound) == pytest.approx(white * math.sqrt(density) / GM.vrw, rel=1e-4)
        assert float(worst) >= float(rate_bound)  # no design beats the bound
    assert (tmp_path / "front.png").stat().st_size > 0


def test_refined_dwells_in_ms_never_overrun_the_budget():
    # 57 dwells that each round up by 0.4 ms overrun a budget their exact sum fits by ~23 ms;
    # the millisecond dwells must fit it again, the longest taking the excess.
    from seqdesign.search.refine import dwells_in_ms

    exact = [10.0006] * 56 + [10.2864]
    available = sum(exact)
    assert sum(round(d, 3) for d in exact) > available + 0.02  # plain rounding overruns
    out = dwells_in_ms(exact, available)
    assert sum(out) <= available
    assert all(round(d * 1000) == d * 1000 for d in out)  # whole milliseconds
    assert max(abs(a - b) for a, b in zip(out[:56], exact[:56], strict=True)) <= 0.0005
    assert exact[56] - 0.03 < out[56] < exact[56] - 0.02  # the ~22 ms overrun, taken off
    assert dwells_in_ms([10.0, 20.0], 30.0) == [10.0, 20.0]  # nothing to take off


@pytest.mark.slow  # a 3-min design search under a MEMS Gauss-Markov profile: ~15 s
def test_design_refuses_when_every_candidate_is_unestimable_at_the_requirements(tmp_path):
    # The ADIS16405 profile (gyro bias instability 60 deg/h) judged against the paper's
    # navigation-grade requirements (0.03 deg/h, asked for: a MEMS profile's own default is the
    # mems requirements): the gyro biases' 3 sigma / requirement is in
    # the thousands, not estimable at that scale for every candidate, so no design can be chosen:
    # a clear refusal naming --requirements, exit 2, no file, no traceback, and nothing else on
    # the terminal (the dwell refinement has no slope to follow: IPOPT is not started on
    # infinite ratios, whose NaN warnings casadi prints itself). A process of its own, since
    # casadi writes to the terminal's stderr, not Python's.
    import subprocess
    import sys

    prof = REPO / "benchmarks" / "profiles" / "adis16405.toml"
    out = tmp_path / "d.toml"
    res = subprocess.run(
        [sys.executable, "-m", "seqdesign.cli", "design", "--budget-min", "3", "--profile", str(prof)]
        + ["--requirements", "paper", "-o", str(out)],
        capture_output=True,
        text=True,
    )
    assert res.returncode == 2 and "Traceback" not in res.stderr, res.stderr
    assert "--requirements mems" in res.stderr and "scores inf" in res.stderr
    assert "NaN" not in res.stderr and "WARNING" not in res.stderr, res.stderr
    assert not out.exists()
