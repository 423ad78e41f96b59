"""A simulated cell configuration in a temporary folder, for the daemon tests and the soak bench."""

import shutil
from pathlib import Path

EXAMPLES = Path(__file__).resolve().parent.parent / "examples"


def make_cell(folder: Path, robot_options: str = "", time_scale: float = 0.005,
              extra: str = "", weld_speed_mm_s: float | None = None) -> Path:
    """Copy the sim-cell example into ``folder`` with local records, socket and log.

    ``weld_speed_mm_s`` replaces the demo job's weld speed: a slow weld lasts long enough that a
    test acting "while the arc is on" cannot see the weld finish first on a loaded machine.
    """
    folder.mkdir(parents=True, exist_ok=True)
    for name in ("demo-job.toml", "sim-calibration.yaml"):
        shutil.copy(EXAMPLES / name, folder / name)
    if weld_speed_mm_s is not None:
        job = folder / "demo-job.toml"
        text = job.read_text()
        assert "[weld]\nspeed_mm_s = 8.0" in text, "the demo job's weld speed moved"
        job.write_text(text.replace("[weld]\nspeed_mm_s = 8.0",
                                    f"[weld]\nspeed_mm_s = {weld_speed_mm_s}"))
    text = (EXAMPLES / "sim-cell.toml").read_text()
    url = f"mock://?seed=1&time_scale={time_scale}" + (f"&{robot_options}" if robot_options
                                                        else "")
    text = (text.replace('url = "mock://?seed=1&time_scale=0.02"', f'url = "{url}"')
            .replace('dir = "../out/sim-cell/records"', 'dir = "records"')
            .replace('socket = "../out/sim-cell/seamguide.sock"', 'socket = "ctl.sock"')
            .replace('log_file = "../out/sim-cell/seamguide.jsonl"', 'log_file = "log.jsonl"'))
    text = text.replace("reconnect_min_s = 0.5", "reconnect_min_s = 0.05")
    cfg = folder / "cell.toml"
    cfg.write_text(text + extra)
    return cfg
