"""A simulated cell configuration in a temporary folder, for the daemon tests and the soak bench."""

import shutil
from pathlib import Path

EXAMPLES = Path(__file__).resolve().parent.parent / "examples"


def make_cell(folder: Path, robot_options: str = "", time_scale: float = 0.005,
              extra: str = "") -> Path:
    """Copy the sim-cell example into ``folder`` with local records, socket and log."""
    folder.mkdir(parents=True, exist_ok=True)
    for name in ("demo-job.toml", "sim-calibration.yaml"):
        shutil.copy(EXAMPLES / name, folder / name)
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
