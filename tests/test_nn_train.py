"""The training run (:class:`thermocal.nn.train.Trainer`) and `thermocal train`'s presets and
help pages."""

from __future__ import annotations

from dataclasses import replace

import pytest

torch = pytest.importorskip("torch")

from thermocal.cli import main  # noqa: E402
from thermocal.nn.commands import PRESETS, SHIPPED  # noqa: E402
from thermocal.nn.data import BurstConfig, ScenePool  # noqa: E402
from thermocal.nn.infer import shipped_model_path  # noqa: E402
from thermocal.nn.model import ModelConfig  # noqa: E402
from thermocal.nn.store import load_model  # noqa: E402
from thermocal.nn.train import TrainConfig, Trainer, train  # noqa: E402

MODEL = ModelConfig(n_frames=3, mu=4, levels=1, kernel=3)
BURSTS = BurstConfig(n_frames=3, crop=32, units=(0, 1))
TINY = TrainConfig(batch=2, steps_per_epoch=2, max_epochs=2, val_bursts=4, workers=0, threads=1)
POOLS = {
    "pool_fn": lambda: ScenePool.training(seed=1, n_procedural=2),
    "val_pool_fn": lambda: ScenePool.training(seed=2, n_procedural=2),
    "log": lambda line: None,
    "progress": False,
}


def weights(path) -> dict[str, torch.Tensor]:
    return load_model(path)[0].state_dict()


def same(a: dict[str, torch.Tensor], b: dict[str, torch.Tensor]) -> bool:
    return a.keys() == b.keys() and all(torch.equal(a[k], b[k]) for k in a)


def without_time(history: list[dict]) -> list[dict]:
    return [{k: v for k, v in row.items() if k != "elapsed_s"} for row in history]


def test_train_is_a_trainer_loop(tmp_path):
    """train() and epoch() + validate() by hand: the same weights, bit for bit (CPU)."""
    res = train(tmp_path / "a.pt", MODEL, BURSTS, TINY, **POOLS)
    assert res.stopped == "max_epochs" and res.steps == 4
    last = torch.load(tmp_path / "a.ckpt", weights_only=False)["model"]

    t = Trainer(tmp_path / "b.pt", MODEL, BURSTS, TINY, **POOLS)
    assert same(weights(tmp_path / "b.pt"), t.model.state_dict())  # the untrained network
    losses = [t.step(t.next_batch()) for _ in range(2)]  # the first epoch, step by step
    scores = [t.validate()]
    stats = t.epoch()
    scores.append(t.validate())
    t.close()
    assert stats["steps"] == 2 and stats["step"] == t.steps == 4
    assert [h["train_loss"] for h in res.history] == [sum(losses) / 2, stats["train_loss"]]
    assert [(h["val_loss"], h["val_mae_c"], h["val_mae_bias_free_c"]) for h in res.history] == (
        scores)
    t.save(tmp_path / "c.pt", scores[-1])
    assert same(weights(tmp_path / "c.pt"), last)
    assert load_model(tmp_path / "c.pt")[2]["meta"]["step"] == 4


def test_checkpoint_and_resume_continue_the_run_identically(tmp_path):
    whole = Trainer(tmp_path / "a.pt", MODEL, BURSTS, TINY, **POOLS).run()

    first = Trainer(tmp_path / "b.pt", MODEL, BURSTS, replace(TINY, max_epochs=1), **POOLS)
    assert first.run().epochs == 1
    first.checkpoint(tmp_path / "copy.ckpt")  # what run() left in b.ckpt, elsewhere
    t = Trainer.resume(tmp_path / "b.pt", replace(TINY, lr=1.0), ckpt=tmp_path / "copy.ckpt",
                       **POOLS)
    assert t.steps == 2 and t.epochs == 1 and t.train_cfg.lr == TINY.lr  # the checkpoint's rate
    res = t.run()
    assert res.steps == whole.steps and without_time(res.history) == without_time(whole.history)
    assert same(weights(tmp_path / "b.pt"), weights(tmp_path / "a.pt"))
    b, a = (torch.load(tmp_path / f"{n}.ckpt", weights_only=False) for n in "ba")
    assert same(b["model"], a["model"]) and same(b["opt"]["state"][0], a["opt"]["state"][0])


# --------------------------------------------------------------------------------------------
# thermocal train
# --------------------------------------------------------------------------------------------
MAIN = ["--out", "--preset", "--chamber", "--init", "--resume", "--max-minutes", "--steps",
        "--frames", "--seed", "--workers", "--threads", "--device", "--help-all", "--help"]
EXPERIMENT = ["--variant", "--mu", "--xi", "--levels", "--kernel", "--degree", "--fpa-input",
              "--centre", "--radiance", "--radial", "--radial-frames", "--calibrated", "--crop",
              "--batch", "--steps-per-epoch", "--max-epochs", "--lr", "--lr-schedule",
              "--val-bursts", "--units", "--val-units", "--scenes", "--fpa-range-c",
              "--temp-mean-range-c", "--redraw-pixel-fpn", "--walk-frames", "--sensor-motion"]


def cli(args: list[str], capsys) -> tuple[int, str, str]:
    try:
        main(args)
        code = 0
    except SystemExit as exc:
        code = exc.code if isinstance(exc.code, int) else 1
    captured = capsys.readouterr()
    return code, captured.out, captured.err


def options(page: str) -> set[str]:
    import re

    return set(re.findall(r"^\s+(?:-\w, )?(--[a-z-]+)", page, flags=re.MULTILINE))


def test_train_help_lists_the_main_options_and_help_all_the_experiment_ones(capsys):
    code, out, _ = cli(["train", "--help"], capsys)
    assert code == 0
    assert options(out) == set(MAIN) and "Experiment options" not in out
    code, out, _ = cli(["train", "--help-all"], capsys)
    assert code == 0
    main_page, experiment_page = out.split("Experiment options:")
    assert options(main_page) == set(MAIN) and options(experiment_page) == set(EXPERIMENT)
    code, out, _ = cli(["train", "--help"], capsys)  # --help-all changed nothing for later
    assert options(out) == set(MAIN)


@pytest.fixture
def configs(monkeypatch):
    """What `thermocal train` would train: the arguments it gives train(), without training."""
    from thermocal.nn import train as train_module

    seen = {}

    def fake(out, model_cfg, burst_cfg, train_cfg, **kw):
        seen.update(model=model_cfg, bursts=burst_cfg, train=train_cfg, **kw)
        return train_module.TrainResult(0, 0, 0.0, 0.0, 0.0, "max_steps", 0.0, [])

    monkeypatch.setattr(train_module, "train", fake)
    return seen


def test_the_default_preset_is_the_shipped_networks_configuration(tmp_path, capsys, configs):
    code, _, err = cli(["train", "--out", str(tmp_path / "m.pt")], capsys)
    assert code == 0, err
    model, _, info = load_model(shipped_model_path("kpn"))  # and how it was trained
    assert configs["model"] == model.config
    bursts = configs["bursts"].to_dict()
    assert {k: bursts[k] for k in info["data"]} == info["data"]
    cmd = info["meta"]["command"].split()
    given = {cmd[i]: cmd[i + 1] for i in range(len(cmd) - 1) if cmd[i].startswith("--")}
    tc = configs["train"]
    assert (tc.lr, tc.lr_schedule, tc.max_epochs, tc.batch, tc.steps_per_epoch) == (
        float(given["--lr"]), given["--lr-schedule"], int(given["--max-epochs"]),
        int(given["--batch"]), int(given["--steps-per-epoch"]))
    assert tc.max_minutes == 30.0 and tc.seed == 42 and configs["val_units"] == (50, 51, 52, 53)
    assert configs["meta"]["preset"] == "shipped"
    assert set(PRESETS["paper"]) <= set(SHIPPED)


def test_paper_preset_and_options_given_win(tmp_path, capsys, configs):
    code, _, err = cli(["train", "--out", str(tmp_path / "m.pt"), "--preset", "paper"], capsys)
    assert code == 0, err
    tc = configs["train"]
    assert (tc.lr, tc.lr_schedule, tc.max_epochs, tc.max_minutes) == (1e-4, "plateau", 60, None)
    assert tc == TrainConfig(device="auto")  # TrainConfig's defaults are the paper's
    code, _, err = cli(["train", "--out", str(tmp_path / "m.pt"), "--preset", "paper", "--lr",
                        "5e-4", "--max-minutes", "3"], capsys)
    assert code == 0, err
    assert (configs["train"].lr, configs["train"].max_minutes) == (5e-4, 3.0)
    assert configs["train"].lr_schedule == "plateau"


def test_hidden_experiment_options_still_work(tmp_path, capsys, configs):
    code, _, err = cli(["train", "--out", str(tmp_path / "m.pt"), "--frames", "5", "--mu", "8",
                        "--levels", "2", "--radial-frames", "--sensor-motion", "--walk-frames",
                        "9", "--redraw-pixel-fpn", "--no-calibrated", "--no-radiance",
                        "--variant", "e2e", "--crop", "32", "--batch", "4", "--lr", "2e-3",
                        "--lr-schedule", "plateau", "--units", "0-3", "--val-units", "60",
                        "--scenes", "5", "--temp-mean-range-c", "-20:40"], capsys)
    assert code == 0, err
    m, b, t = configs["model"], configs["bursts"], configs["train"]
    assert (m.n_frames, m.mu, m.levels, m.variant, m.radial_frames, m.calibrated, m.radiance) == (
        5, 8, 2, "e2e", True, False, False)
    assert (b.crop, b.walk_frames, b.sensor_motion, b.redraw_pixel_fpn, b.units) == (
        32, 9, True, True, (0, 1, 2, 3))
    assert b.temp_mean_range_c == (-20.0, 40.0) and configs["val_units"] == (60,)
    assert (t.batch, t.lr, t.lr_schedule) == (4, 2e-3, "plateau")
    code, _, err = cli(["train", "--out", str(tmp_path / "m.pt"), "--lr-schedule", "cosine"],
                       capsys)
    assert code == 2 and "lr-schedule" in err
