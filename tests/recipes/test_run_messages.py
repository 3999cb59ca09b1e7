"""What a run says at its start: the frame budget, then a measured estimate of its duration."""

from types import SimpleNamespace

from morl_trl.runs import run as run_module  # the messages live with the Run object (runs/run.py)


def _cfg(**kw):
    base = dict(algo="envelope", env_id="MOLavaGridDR-v0", seed=0, device="cpu", frames=60_000,
                init_random_frames=10_000, eval_interval=20_000, eval_weights=8)
    return SimpleNamespace(**{**base, **kw})


def test_start_line_gives_the_frame_budget():
    line = run_module.start_line(_cfg(), 0, False)
    assert line.startswith("start: envelope on MOLavaGridDR-v0, seed 0, cpu: frame budget 60,000 (60,000 to go, "
                           "10,000 of them random before learning), about 4 evaluations of 8 weights")
    assert run_module.start_line(_cfg(), 40_000, True).startswith("resume: ")


def test_duration_estimate_is_measured_after_the_warm_up(monkeypatch):
    clock = [100.0]
    monkeypatch.setattr(run_module.time, "perf_counter", lambda: clock[0])
    eta = run_module._DurationEstimate(_cfg(), 0)
    assert eta.update(5_000, [], 20_000) is None          # random warm-up: no learning speed yet
    assert eta.update(10_240, [], 20_000) is None         # learning starts: the measurement begins
    clock[0] += 10.0
    assert eta.update(10_640, [], 20_000) is None         # 10 s: not yet a stable rate
    clock[0] += 10.0
    line = eta.update(11_240, [30.0], 20_000)             # 1,000 frames in 20 s: 50 frames/s
    # 48,760 frames at 50 frames/s = 975.2 s, + 3 evaluations (20k, 40k, 60k) of 30 s = 1065 s
    assert line == ("estimated duration: 17 min 45 s more (48,760 frames at 50 frames/s learning, measured over "
                    "1,000 frames, + 3 evaluations of ~30 s)")
    clock[0] += 100.0
    assert eta.update(20_000, [30.0], 40_000) is None     # said once
    assert run_module._hms(2 * 3600 + 61) == "2 h 01 min"
