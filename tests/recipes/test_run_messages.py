"""What a run says: the frame budget at its start, then a measured estimate of its duration,
renewed after each evaluation, with the evaluations counted in it."""

from types import SimpleNamespace

from morl_trl.runs import run as run_module  # the start line lives with the Run object (runs/run.py)
from morl_trl.runs.estimate import END_EVALUATIONS, END_SECONDS, DurationEstimate, hms


def _cfg(**kw):
    base = dict(algo="envelope", env_id="MOLavaGridDR-v0", seed=0, device="cpu", frames=60_000,
                init_random_frames=10_000, eval_interval=20_000, eval_weights=8)
    return SimpleNamespace(**{**base, **kw})


def test_start_line_gives_the_frame_budget():
    line = run_module.start_line(_cfg(), 0, False)
    assert line.startswith("start: envelope on MOLavaGridDR-v0, seed 0, cpu: frame budget 60,000 (60,000 to go, "
                           "10,000 of them random before learning), about 4 evaluations of 8 weights")
    assert run_module.start_line(_cfg(), 40_000, True).startswith("resume: ")
    one = run_module.start_line(_cfg(frames=2_000, init_random_frames=500), 0, False)
    assert "random before learning), 1 evaluation of 8 weights;" in one  # not "about 1 evaluations"


def test_duration_estimate_is_measured_after_the_warm_up_and_counts_evaluations():
    clock = [100.0]
    eta = DurationEstimate(_cfg(), 0, clock=lambda: clock[0])
    eta.evaluated(0, 2.0)                                  # the untrained policy: 2 s
    clock[0] += 2.0
    eta.batch(5_000)                                       # random warm-up: not a learning speed
    clock[0] += 5.0
    eta.batch(10_240)                                      # learning starts: the measurement begins
    assert eta.first_line(10_240, 20_000) is None
    clock[0] += 10.0
    eta.batch(10_640)
    assert eta.first_line(10_640, 20_000) is None          # 10 s: not yet a stable rate
    clock[0] += 10.0
    eta.batch(11_240)                                      # 1,000 frames in 20 s: 50 frames/s
    line = eta.first_line(11_240, 20_000)
    # 48,760 frames at 50 frames/s = 975.2 s, + 3 evaluations (20k, 40k, 60k) of 2 s, + the end (7 x 2 + 4 s)
    assert (END_EVALUATIONS, END_SECONDS) == (7.0, 4.0)
    assert line == ("estimated duration: 16 min 39 s more (48,760 frames at 50 frames/s learning, measured over the "
                    "last 1,000 frames, + 3 evaluations of ~2 s, an untrained policy's, + ~18 s for the end)")
    assert eta.first_line(11_300, 20_000) is None          # said once; renewed after evaluations (line)
    # an evaluation of the trained policy (30 s) is left out of the learning rate and sets the evaluations' length
    clock[0] += 30.0
    eta.evaluated(20_000, 30.0)
    clock[0] += 20.0
    eta.batch(12_240)                                      # 1,000 frames in 20 s of learning: still 50/s
    assert eta.rate() == (50.0, 2_000)                     # (2,000 frames in 40 s, the 30 s evaluation left out)
    assert eta.seconds_left(12_240, 40_000) == 47_760 / 50 + 2 * 30.0 + 7 * 30.0 + 4.0
    assert eta.seconds_left(60_000, 80_000) == 7 * 30.0 + 4.0 and eta.evaluations_left(60_000, 80_000) == 0


def test_the_learning_rate_is_the_last_minutes():
    clock = [0.0]
    eta = DurationEstimate(_cfg(init_random_frames=0), 0, clock=lambda: clock[0])
    for _ in range(60):                                    # 60 s at 100 frames/s
        clock[0] += 1.0
        eta.batch(int(clock[0] * 100))
    frames = 6_000
    for _ in range(60):                                    # then 60 s at 50 frames/s (a busier machine)
        clock[0] += 1.0
        frames += 50
        eta.batch(frames)
    assert eta.rate() == (50.0, 3_000)


def test_hms():
    assert (hms(2 * 3600 + 61), hms(189), hms(41.6)) == ("2 h 01 min", "3 min 09 s", "42 s")
