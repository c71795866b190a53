"""thermocal campaign (issue 21): recordings as flight tasks on a 2-worker LocalCluster give the
bytes of sequential flights; a failed recording is reported, not fatal; bad input is one line."""

from __future__ import annotations

import asyncio
import json
import shutil
import time
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("distributed")

from distributed.diagnostics.plugin import WorkerPlugin  # noqa: E402

from thermocal.cores import available_cores  # noqa: E402
from thermocal.errors import InvalidInputError  # noqa: E402
from thermocal.pipeline import campaign  # noqa: E402
from thermocal.pipeline.campaign import campaign_tasks, run_campaign  # noqa: E402
from thermocal.pipeline.flight import FlightOptions, process_flight  # noqa: E402


@pytest.fixture(scope="module")
def data(tmp_path_factory):
    """A polynomial calibration of one unit and two short UAV passes of it."""
    from thermocal.evaluation.suites.campaign import recordings_and_calibration

    tmp = tmp_path_factory.mktemp("campaign")
    recordings_and_calibration(tmp, frames=25, count=2, size=(64, 48))
    return tmp


def _options(data: Path) -> FlightOptions:
    return FlightOptions(method="mean", calibration=str(data / "cal.h5"), stride=3,
                         preview_every=2)


def _outputs(out: Path) -> dict[str, bytes]:
    """Every output but those holding timings (summary, report), by path."""
    return {str(p.relative_to(out)): p.read_bytes() for p in sorted(out.rglob("*"))
            if p.is_file() and p.name not in ("summary.json", "report.html")}


def test_a_campaign_gives_the_bytes_of_sequential_flights_and_resumes(data, tmp_path):
    recordings = [data / "pass0", data / "pass1"]
    for r in recordings:
        process_flight(r, tmp_path / "seq" / r.name, _options(data))
    out = tmp_path / "campaign"
    tasks = campaign_tasks(recordings, out, _options(data))
    steps: list[int] = []
    summary = run_campaign(tasks, out, workers=2, progress=steps.append)
    assert summary["failed"] == 0 and summary["workers"] == 2
    # the bar moves as the workers' groups finish (their events), not once a recording: every
    # frame counted once
    assert sum(steps) == sum(t.frames for t in tasks) and len(steps) > len(tasks), steps
    # a run's events go to a topic of its own (campaigns sharing a scheduler kept apart), and
    # a task given none sends none
    assert campaign._progress_events(tasks[0])(7) is None
    assert [r["name"] for r in summary["recordings"]] == ["pass0", "pass1"]
    for r in recordings:
        seq, par = _outputs(tmp_path / "seq" / r.name), _outputs(out / r.name)
        assert len(seq) > 10 and seq == par
        assert (out / r.name / "report.html").is_file()
    assert json.loads((out / "campaign.json").read_text())["failed"] == 0
    # each worker registers on its share of the cores
    share = max(1, available_cores() // 2)
    flight_options = json.loads((out / "pass0" / "summary.json").read_text())["options"]
    assert flight_options["registration_threads"] == share
    assert flight_options["pivot_workers"] == share  # its pivots at once on its share
    # rerun: every map is kept (resume), none remade
    sorted((out / "pass1" / "temps").glob("frame_??????.tiff"))[0].unlink()
    again = run_campaign(campaign_tasks(recordings, out, _options(data)), out, workers=1)
    by_name = {r["name"]: r for r in again["recordings"]}
    assert by_name["pass0"]["processed"] == 0 and by_name["pass1"]["processed"] == 1
    resumed, seq = _outputs(out / "pass1"), _outputs(tmp_path / "seq" / "pass1")
    assert resumed.pop("log.jsonl") != seq.pop("log.jsonl")  # the retry is logged
    assert resumed == seq


def test_a_failed_recording_is_reported_and_the_others_finish(data, tmp_path):
    good, gone = data / "pass0", tmp_path / "gone"
    shutil.copytree(data / "pass1", gone)
    tasks = campaign_tasks([gone, good], tmp_path / "out", _options(data))
    shutil.rmtree(gone)  # lost after the campaign checked it
    summary = run_campaign(tasks, tmp_path / "out", workers=2)
    gone_result, good_result = summary["recordings"]
    assert summary["failed"] == 1
    assert not gone_result["ok"] and "gone" in gone_result["error"]
    assert good_result["ok"] and good_result["processed"] > 0


def test_same_names_are_made_unique_whatever_the_order_given(data, tmp_path):
    """Recordings of one name are numbered in the order of their paths, not of the command
    line: a rerun with the inputs in another order finds its own folders (it failed every
    recording as "another run's")."""
    other = tmp_path / "b" / "pass0"
    shutil.copytree(data / "pass0", other)
    first, second = sorted([(data / "pass0").resolve(), other.resolve()], key=str)
    for order in ([data / "pass0", other], [other, data / "pass0"]):
        tasks = campaign_tasks(order, tmp_path / "out", _options(data))
        names = {Path(t.recording).resolve(): t.name for t in tasks}
        assert names == {first: "pass0", second: "pass0-2"}


@pytest.fixture
def stranger():
    """A local port that accepts and then never answers (``silent``), or answers as a web
    server would (``http``, a dashboard's port): its address."""
    import socket
    import threading

    servers = []

    def start(kind: str) -> str:
        server = socket.socket()
        server.bind(("127.0.0.1", 0))
        server.listen(4)
        servers.append(server)

        def serve() -> None:
            while True:
                try:
                    conn, _ = server.accept()
                except OSError:
                    return
                servers.append(conn)
                if kind == "http":
                    conn.recv(64)
                    conn.sendall(b"HTTP/1.1 400 Bad Request\r\nContent-Length: 0\r\n\r\n" * 4)

        threading.Thread(target=serve, daemon=True).start()
        return f"tcp://127.0.0.1:{server.getsockname()[1]}"

    yield start
    for s in servers:
        s.close()


@pytest.mark.parametrize("kind, message", [
    ("silent", "did not answer as a Dask scheduler within 2 s"),
    ("http", "is not a Dask scheduler (it answered otherwise"),
])
def test_a_scheduler_address_that_is_no_scheduler_is_refused_in_time(data, tmp_path, capsys,
                                                                      monkeypatch, stranger,
                                                                      kind, message):
    """A port that accepts and never answers hung the command for good; a web server's (the
    dashboard's) answer was read as a 3-EiB message ("out of memory"): one line, exit 2, in the
    connect timeout, nothing written."""
    from thermocal.cli import main

    monkeypatch.setattr(campaign, "CONNECT_TIMEOUT_S", 2)
    out = tmp_path / "out"
    started = time.perf_counter()
    with pytest.raises(SystemExit) as e:
        main(["campaign", str(data / "pass0"), "--out", str(out), "--scheduler",
              stranger(kind)])
    err = capsys.readouterr().err.strip()
    assert e.value.code == 2 and "\n" not in err and message in err, err
    assert time.perf_counter() - started < 20 and not out.exists()


def test_a_worker_address_is_refused_and_a_scheduler_without_workers_said():
    """A worker's address given as the scheduler's: one line naming what it is; a scheduler
    with no workers yet (a dask-jobqueue cluster still queueing them): connected, with a
    warning that the tasks wait."""
    from distributed import LocalCluster

    from thermocal.calibration.base import ThermocalWarning

    with LocalCluster(n_workers=1, threads_per_worker=1, processes=False,
                      dashboard_address=":0") as cluster:
        worker = next(iter(cluster.workers.values())).address
        with pytest.raises(InvalidInputError, match="is a Dask Worker, not a scheduler"):
            campaign.connect(worker, 1)
    with LocalCluster(n_workers=0, processes=False, dashboard_address=":0") as cluster:
        with pytest.warns(ThermocalWarning, match="has no workers yet"):
            client = campaign.connect(cluster.scheduler_address, 1)
        client.close()

        async def inside_a_running_loop() -> None:  # a notebook's: the check still asks
            campaign._check_scheduler(cluster.scheduler_address)

        asyncio.run(inside_a_running_loop())


@pytest.mark.parametrize("args, message", [
    (["{data}/cal.h5"], "cal.h5"),
    (["{data}/pass0", "{data}/pass0"], "given twice"),
    (["{data}/pass0", "{data}/pass0/frames.tiff"], "frames.tiff: given twice"),  # folder, file
    (["{data}/pass0", "--scheduler", "tcp://127.0.0.1:9"], "cannot reach the Dask scheduler"),
    (["{data}/pass0", "--workers", "0"], "--workers"),
    (["{data}/pass0", "--method", "mean"], "--calibration"),
])
def test_bad_campaign_input_is_one_line_exit_2_and_writes_nothing(data, tmp_path, capsys,
                                                                 monkeypatch, args, message):
    from thermocal.cli import main

    monkeypatch.setattr(campaign, "CONNECT_TIMEOUT_S", 2)
    out = tmp_path / "out"
    with pytest.raises(SystemExit) as e:
        main(["campaign", *[a.replace("{data}", str(data)) for a in args], "--out", str(out)])
    err = capsys.readouterr().err.strip()
    assert e.value.code == 2 and "\n" not in err and message in err, err
    assert not out.exists()


@pytest.mark.parametrize("method, warned", [("e2e", True), ("kpn", False)])
def test_a_campaign_says_the_caveat_of_a_sigma_on_its_console(data, tmp_path, capsys,
                                                              monkeypatch, method, warned):
    """The workers' warnings stay in campaign.json: a method whose σ is known not to hold
    somewhere (e2e) is said on the console too, as a flight says it."""
    from thermocal.cli import main

    done = {"recordings": [{"name": "pass0", "ok": True, "processed": 3, "sigma": True,
                            "skipped_already_done": 0, "failed_groups": 0}],
            "failed": 0, "wall_time_s": 1.0}
    monkeypatch.setattr(campaign, "campaign_tasks", lambda *args, **kwargs: [])
    monkeypatch.setattr(campaign, "run_campaign", lambda *args, **kwargs: done)
    main(["campaign", str(data / "pass0"), "--out", str(tmp_path / "out"), "--method",
          method])
    err = capsys.readouterr().err
    assert (f"warning: {method}: its σ is fitted on bursts of the scenes" in err) == warned


def test_a_campaign_says_its_workers_warnings_on_its_console(data, tmp_path, capsys,
                                                            monkeypatch):
    """What the workers warned (kept in campaign.json) reaches the console too, as a flight
    says it: each text once with the recordings that raised it; the σ caveat once."""
    from thermocal.cli import main
    from thermocal.nn.variants import sigma_warning

    said = sigma_warning("e2e")
    done = {"recordings": [
        {"name": "a", "ok": True, "processed": 3, "sigma": True, "skipped_already_done": 0,
         "failed_groups": 0, "warnings": ["2 damaged frames left out", said]},
        {"name": "b", "ok": True, "processed": 3, "sigma": True, "skipped_already_done": 0,
         "failed_groups": 0, "warnings": ["2 damaged frames left out"]},
        {"name": "c", "ok": True, "processed": 3, "sigma": True, "skipped_already_done": 0,
         "failed_groups": 0, "warnings": []}],
        "failed": 0, "wall_time_s": 1.0}
    monkeypatch.setattr(campaign, "campaign_tasks", lambda *args, **kwargs: [])
    monkeypatch.setattr(campaign, "run_campaign", lambda *args, **kwargs: done)
    main(["campaign", str(data / "pass0"), "--out", str(tmp_path / "out"), "--method", "e2e"])
    err = capsys.readouterr().err.splitlines()
    assert err.count("thermocal: warning: a, b: 2 damaged frames left out") == 1, err
    assert sum(said in line for line in err) == 1, err
    assert len(err) == 2, err


def test_a_campaign_gives_selfcal_its_family(data, tmp_path, monkeypatch):
    """--family reaches every flight of a campaign (a boson campaign's selfcal started from
    tau2's average unit: a campaign had no --family)."""
    from thermocal.cli import main

    given = []
    monkeypatch.setattr(campaign, "campaign_tasks",
                        lambda inputs, out, options: given.append(options) or [])
    monkeypatch.setattr(campaign, "run_campaign", lambda *args, **kwargs: {
        "recordings": [], "failed": 0, "wall_time_s": 0.0})
    main(["campaign", str(data / "pass0"), "--out", str(tmp_path / "out"), "--method",
          "selfcal", "--family", "boson"])
    main(["campaign", str(data / "pass0"), "--out", str(tmp_path / "out"), "--method",
          "selfcal"])
    assert [o.family for o in given] == ["boson", "tau2"]


def test_a_recording_made_with_other_options_fails_alone_in_one_line(data, tmp_path, capsys):
    """A campaign rerun into a folder whose first recording was made at another stride: that
    recording is refused (resuming would mix two runs' maps), the other is made; the results
    go to stdout and stderr holds the one line of the failure."""
    from thermocal.cli import main

    out = tmp_path / "out"
    common = ["--out", str(out), "--method", "mean", "--calibration", str(data / "cal.h5"),
              "--workers", "1", "--preview-every", "0"]
    main(["campaign", str(data / "pass0"), *common, "--stride", "5"])
    capsys.readouterr()
    with pytest.raises(SystemExit) as e:
        main(["campaign", str(data / "pass0"), str(data / "pass1"), *common, "--stride", "3"])
    captured = capsys.readouterr()
    assert e.value.code == 2
    assert captured.err.count("\n") == 1, captured.err
    assert captured.err.startswith("thermocal: error: 1 of 2 recordings failed"), captured.err
    assert "pass0: failed:" in captured.out and "--stride 5 → 3" in captured.out, captured.out
    assert "pass1: " in captured.out and "maps made" in captured.out, captured.out


class _DiesOn(WorkerPlugin):
    """A worker plugin that kills its worker process when it starts a task whose key holds
    ``name`` (a worker lost mid-task: out of memory, a node gone)."""

    def __init__(self, name: str) -> None:
        self.name = name

    def transition(self, key, start, finish, **kwargs) -> None:  # noqa: D102
        import os

        if finish == "executing" and self.name in str(key):
            os._exit(1)


def test_a_worker_that_dies_mid_task_is_reported_and_the_others_finish(data, tmp_path):
    import sys

    import cloudpickle
    from distributed import Client, LocalCluster

    cloudpickle.register_pickle_by_value(sys.modules[__name__])  # the plugin, to the workers
    tasks = campaign_tasks([data / "pass0", data / "pass1"], tmp_path / "out", _options(data))
    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                      dashboard_address=":0") as cluster, Client(cluster) as client:
        client.register_plugin(_DiesOn("flight-pass0"), name="dies")
        summary = run_campaign(tasks, tmp_path / "out", scheduler=cluster.scheduler_address)
    dead, good = summary["recordings"]
    assert summary["failed"] == 1 and summary["scheduler"] == cluster.scheduler_address
    assert not dead["ok"] and "KilledWorker" in dead["error"]
    # its task may have run again after a worker it shared the cluster with died: it resumed
    assert good["ok"] and good["processed"] + good["skipped_already_done"] == good["groups"] > 0
    assert json.loads((tmp_path / "out" / "campaign.json").read_text())["failed"] == 1


def test_a_long_recording_runs_in_segments_and_gives_the_bytes_of_one_flight(tmp_path,
                                                                            monkeypatch):
    """A recording of 3 batches (1,100 frames), one batch per segment: three segment tasks and
    a finishing one on the 2-worker cluster give the bytes of one `thermocal flight`; the
    campaign reports one recording with the summed counts."""
    from thermocal.evaluation.suites.campaign import recordings_and_calibration

    (rec,), cal = recordings_and_calibration(tmp_path, frames=1100, count=1, size=(32, 24))
    options = FlightOptions(method="mean", calibration=str(cal), stride=16, preview_every=8)
    monkeypatch.setattr(campaign, "SEGMENT_BATCHES", 1)  # where the tasks are made
    tasks = campaign_tasks([rec], tmp_path / "out", options)
    assert [t.segment for t in tasks] == [(0, 1), (1, 2), (2, 3)]
    assert sum(t.frames for t in tasks) == 1100
    seq = process_flight(rec, tmp_path / "seq", options)
    summary = run_campaign(tasks, tmp_path / "out", workers=2)
    (result,) = summary["recordings"]
    assert summary["failed"] == 0 and result["ok"] and result["segments"] == 3
    assert result["processed"] == seq["processed"] > 0
    assert _outputs(tmp_path / "out" / rec.name) == _outputs(tmp_path / "seq")
    assert (tmp_path / "out" / rec.name / "report.html").is_file()


def test_a_segments_warnings_reach_its_recordings_result_once(tmp_path, monkeypatch):
    """A recording in segments: what its flight warns (an e2e σ's caveat, say) is kept by each
    segment task, not shown there, and warned once by the finishing task, into the
    recording's result (it was dropped)."""
    import warnings
    from dataclasses import replace

    from thermocal.pipeline import flight, report

    said = "e2e: its σ is fitted on bursts of the scenes it was trained on"

    def segment_flight(recording, out_dir, options, *, segment, progress=None):
        warnings.warn(said, UserWarning, stacklevel=2)
        return {"segment": list(segment), "wall_time_s": 1.0}

    monkeypatch.setattr(flight, "process_flight", segment_flight)
    tasks = [campaign.CampaignTask("a", "a.tiff", str(tmp_path), 10, FlightOptions(),
                                   segment=span) for span in ((0, 1), (1, 2))]
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # kept, not shown: it would raise here
        done = [campaign._run_task(t)["segment"] for t in tasks]
    assert [d["warnings"] for d in done] == [[said], [said]]
    counts = {"processed": 2, "skipped_already_done": 0, "failed": 0, "groups": 2}
    monkeypatch.setattr(flight, "finish_segments", lambda *args: counts)
    monkeypatch.setattr(report, "write_report", lambda out: None)
    result = campaign._finish_task(replace(tasks[0], segment=None), done)
    assert result["ok"] and result["warnings"] == [said]


def test_two_tasks_at_once_on_one_worker_keep_their_own_warnings(tmp_path, monkeypatch):
    """A worker of a user's cluster may run two tasks at once on two threads of one process:
    each recording's result lists its own flight's warnings, not the other's (they were
    recorded through warnings.catch_warnings, which one process shares between threads)."""
    import threading
    import warnings

    from thermocal.pipeline import flight, report

    both_in = threading.Barrier(2, timeout=10)
    counts = {"processed": 1, "skipped_already_done": 0, "failed": 0, "groups": 1}

    def one_flight(recording, out_dir, options, *, progress=None):
        for step in range(3):  # each warns while the other is inside its own flight too
            both_in.wait()
            warnings.warn(f"{recording}: warning {step}", UserWarning, stacklevel=2)
        return counts

    monkeypatch.setattr(flight, "process_flight", one_flight)
    monkeypatch.setattr(report, "write_report", lambda out: None)
    tasks = [campaign.CampaignTask(name, f"{name}.tiff", str(tmp_path / name), 10,
                                   FlightOptions()) for name in ("a", "b")]
    results: dict[str, dict] = {}
    threads = [threading.Thread(target=lambda t=t: results.__setitem__(
        t.name, campaign._run_task(t))) for t in tasks]
    for t in threads:
        t.start()
    for t in threads:
        t.join(30)
    for name in ("a", "b"):
        assert results[name]["ok"]
        assert results[name]["warnings"] == [f"{name}.tiff: warning {k}" for k in range(3)]
    with warnings.catch_warnings(record=True) as after:  # the process's state given back
        warnings.simplefilter("default")
        warnings.warn("after", UserWarning, stacklevel=1)
    assert [str(w.message) for w in after] == ["after"]


def test_task_keys_cannot_collide_and_a_short_recording_is_one_task(data, tmp_path):
    """Keys put the kind of task first (a recording named ``a-finish`` and ``a``'s finishing
    task differ); a recording too short for a group is left to its task to report."""
    from thermocal.io.recording import Recording, write_recording

    seg = campaign.CampaignTask("a", "a", "out/a", 2000, _options(data), segment=(0, 2))
    keys = {campaign._task_key(seg), campaign._task_key(seg, finish=True),
            campaign._task_key(campaign.CampaignTask("a-finish", "x", "out/x", 9,
                                                     _options(data))),
            campaign._task_key(campaign.CampaignTask("a-segment-0", "y", "out/y", 9,
                                                     _options(data)))}
    assert len(keys) == 4
    short, _ = write_recording(tmp_path / "short.tiff", Recording(
        np.full((2, 48, 64), 8000, np.uint16), fpa_c=np.full(2, 28.0), time_s=np.arange(2.0)))
    tasks = campaign_tasks([short, data / "pass0"], tmp_path / "out", _options(data))
    assert [t.segment for t in tasks] == [None, None]


def test_numbered_names_never_take_another_recordings_name(tmp_path):
    """x/a, y/a and z/a-2: y/a is not numbered a-2, which z/a-2's own name is (both wrote into
    OUT/a-2)."""
    from thermocal.pipeline.campaign import _output_names

    paths = []
    for folder, name in (("x", "a"), ("y", "a"), ("z", "a-2"), ("w", "a")):
        (tmp_path / folder).mkdir()
        paths.append(tmp_path / folder / f"{name}.tiff")
        paths[-1].write_bytes(b"")
    for order in (paths, paths[::-1]):
        names = _output_names(order)
        assert len(set(names.values())) == 4
        assert names[(tmp_path / "z" / "a-2.tiff").resolve()] == "a-2"
        assert sorted(names.values()) == ["a", "a-2", "a-3", "a-4"]


def test_a_rerun_with_inputs_left_out_or_added_keeps_each_recordings_folder(data, tmp_path):
    """A campaign run again on some of its recordings, or with another of the same name:
    each keeps the folder the first run gave it (a rerun on the second alone was refused as
    "another run's"), and campaign.json keeps the recordings this run left out."""
    other = tmp_path / "b" / "pass0"
    shutil.copytree(data / "pass0", other)
    out = tmp_path / "out"
    first, second = sorted([(data / "pass0").resolve(), other.resolve()], key=str)
    both = run_campaign(campaign_tasks([first, second], out, _options(data)), out, workers=1)
    assert [r["name"] for r in both["recordings"]] == ["pass0", "pass0-2"]
    again = run_campaign(campaign_tasks([second], out, _options(data)), out, workers=1)
    assert [(r["name"], r["ok"]) for r in again["recordings"]] == [("pass0-2", True)]
    assert [r["name"] for r in again["earlier"]] == ["pass0"]
    third = tmp_path / "c" / "pass0"
    shutil.copytree(data / "pass0", third)
    names = {Path(t.recording).resolve(): t.name
             for t in campaign_tasks([third, first], out, _options(data))}
    assert names == {first: "pass0", third.resolve(): "pass0-3"}


def test_the_workers_leave_ctrl_c_to_the_command():
    """The LocalCluster's worker processes start with SIGINT ignored, so that Ctrl-C (sent to
    the whole process group) is answered by the command alone, in one line (each worker printed
    its KeyboardInterrupt traceback); the command's own handler is as it was."""
    import signal

    before = signal.getsignal(signal.SIGINT)
    client = campaign.connect(None, 1)
    try:
        ignored = client.run(lambda: signal.getsignal(signal.SIGINT) == signal.SIG_IGN)
    finally:
        client.close()
        client.cluster.close()
    assert list(ignored.values()) == [True]
    assert signal.getsignal(signal.SIGINT) is before


def test_fpa_c_given_to_a_campaign_is_every_flights_as_flight_takes_it(data, tmp_path,
                                                                       capsys):
    """`thermocal campaign --fpa-c T` (for files that carry no FPA temperature, FLIR's) gives
    each recording's flight that FPA temperature: the bytes of `thermocal flight --fpa-c T`."""
    from tests.cli_run import run

    sidecar = json.loads((data / "pass0" / "frames.json").read_text())
    fpa = str(round(float(np.median(sidecar["fpa_c"])) + 0.5, 2))  # not the sidecar's own
    common = ["--method", "mean", "--calibration", str(data / "cal.h5"), "--stride", "3",
              "--preview-every", "2", "--fpa-c", fpa]
    for args in (["flight", str(data / "pass0"), "--out", str(tmp_path / "seq" / "pass0")],
                 ["campaign", str(data / "pass0"), "--out", str(tmp_path / "campaign"),
                  "--workers", "1"]):
        code, _, err = run(args + common, capsys)
        assert code == 0, err
    seq, par = _outputs(tmp_path / "seq" / "pass0"), _outputs(tmp_path / "campaign" / "pass0")
    assert len(seq) > 10 and seq == par
    options = json.loads((tmp_path / "campaign" / "pass0" / "summary.json").read_text())
    assert options["options"]["fpa_c"] == float(fpa)
