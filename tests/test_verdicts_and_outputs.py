"""Golden verdicts, output-folder checks and farm attempts pinned by what they report, so a wrong branch
fails (docs/testing.md "magnitude"): a warning then a failure is a failure, a run missing only its last
frame is incomplete, every damaged frame is named (not only the first), and an attempt whose worker went
away without a word is a lost worker's, not a success."""
from __future__ import annotations

import io
import json

import numpy as np
import pytest

from fraytool.golden.compare import FAIL, PASS, WARN, FrameVerdict

pytestmark = pytest.mark.fast


@pytest.mark.parametrize("order", [(WARN, FAIL), (FAIL, WARN), (WARN, WARN), (FAIL, FAIL)])
def test_a_frames_verdict_is_its_worst_flag_in_any_order(order):
    v = FrameVerdict(3)
    assert v.status == PASS
    for status in order:
        v.flag(status, "x")
    assert v.status == (FAIL if FAIL in order else WARN)
    assert len(v.reasons) == 2


def _shot(tmp_path, frames):
    from fraytool.sim.run import simulate_to_disk
    from helpers import small_scene

    spec = small_scene(frames=6)
    out = tmp_path / "shot"
    simulate_to_disk(spec, out, frames=frames, progress=False, stream=io.StringIO())
    return spec, out


def test_a_run_missing_only_its_last_frame_is_incomplete(tmp_path):
    from fraytool.commands.check_outputs import folder_report

    spec, out = _shot(tmp_path, frames=5)  # the scene asks for 6
    report = folder_report(out, spec)
    assert not report["intact"] and report["frames_verified"] == 5
    assert any("frames 5-5 of 6 are missing" in p for p in report["problems"]), report["problems"]
    assert folder_report(out, None)["intact"]  # without the scene: the 5 frames the run planned


def test_every_damaged_frame_is_named_not_only_the_first(tmp_path):
    from fraytool.io.frame_store import FrameStore

    spec, out = _shot(tmp_path, frames=6)
    store = FrameStore(out)
    for k in (2, 3, 5):
        path = store.frame_path(k)
        data = bytearray(path.read_bytes())
        data[len(data) // 2] ^= 0xFF
        path.write_bytes(bytes(data))
    survey = store.survey()
    assert survey.good_frames == 2
    named = [k for k in range(6) if any(store.frame_path(k).name in p for p in survey.problems)]
    assert named == [2, 3, 5], survey.problems


def test_an_attempt_whose_worker_went_away_unannounced_is_a_lost_worker():
    """The task starts on worker a, then starts again on worker b with no remove-worker event between (the
    scheduler's event lost or late): a's attempt ended as a lost worker, and job.json says so."""
    from fraytool.farm.tasks import ATTEMPT_TOPIC
    from fraytool.farm.watch import FarmWatch
    from test_farm_report import _FakeClient

    client, stream = _FakeClient(), io.StringIO()
    client.workers = 2
    watch = FarmWatch(client, stream)
    send = client.handlers[ATTEMPT_TOPIC]
    a, b = "tcp://10.0.0.2:4001", "tcp://10.0.0.3:4002"
    send((1.0, {"key": "sim-s", "event": "start", "time": 100.0, "worker": a, "process": "h2:11"}))
    send((1.0, {"key": "sim-s", "event": "start", "time": 130.0, "worker": b, "process": "h3:12"}))
    watch.poll()
    result = {"frames": 6, "attempt": {"worker": b, "process": "h3:12", "start": 130.0, "end": 140.0}}
    attempts = watch.finished("sim-s", result=result)
    assert [(x["worker"], x["outcome"]) for x in attempts] == [(a, "lost worker"), (b, "ok")]
    assert [x["seconds"] for x in attempts] == [30.0, 10.0]
