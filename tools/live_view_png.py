"""A screenshot of the live view (``aerostereo-ingest record --mission``) in a real terminal, as a PNG for the docs.

    PYTHONPATH=. .venv/bin/python tools/live_view_png.py --out docs/live_view.png [--at 10]

The virtual drone flies the default orbit's first 3 waypoints with its gimbal stuck at -80 degrees from 25 s to 30 s
of flight and serves it over TCP (``sim.drone.link.FrameServer``) at real time from 18 s of flight; ``record
--mission`` runs in a tmux session 150x24 (``send-keys``), and the screen is read ``--at`` seconds later
(``capture-pane -e``: text and its bold / reverse video), then Ctrl-C ends the recording. The text is drawn in
DejaVu Sans Mono (matplotlib's copy) onto a dark background.
"""

from __future__ import annotations

import argparse
import re
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from matplotlib import font_manager  # noqa: E402
from PIL import Image, ImageDraw, ImageFont  # noqa: E402

from flightplan import litchi  # noqa: E402
from sim.drone import FlightFaults, Imperfections, fly  # noqa: E402
from sim.drone.flight_faults import GimbalStuck  # noqa: E402
from sim.drone.link import FrameServer, duml_frames  # noqa: E402
from sim.drone.mission import home_below_first_waypoint, waypoints_from_litchi  # noqa: E402
from tests.sim.drone_helpers import short_orbit_csv  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
COLUMNS, ROWS = 150, 24
FROM_S = 18.0
SGR = re.compile(r"\x1b\[([0-9;]*)m")
FOREGROUND, BACKGROUND, FONT_PX = (220, 220, 220), (24, 24, 28), 15


def screen_text(seconds: float, work: Path) -> str:
    """The live view's screen (with its SGR codes) ``seconds`` after ``record --mission`` started in tmux."""
    mission_csv = short_orbit_csv(work / "arc.csv")
    waypoints = waypoints_from_litchi(litchi.read_mission_csv(mission_csv))
    mission = fly(waypoints, home_below_first_waypoint(waypoints, 100.0), Imperfections.realistic(), seed=5,
                  faults=FlightFaults(gimbal_stuck=GimbalStuck(25.0, 5.0, -80.0)))
    server = FrameServer([frame for frame in duml_frames(mission) if frame.t_s >= FROM_S], from_s=FROM_S)
    server.start()
    session = f"aerostereo-screenshot-{server.port}"
    tmux = shutil.which("tmux") or sys.exit("tools/live_view_png.py: error: tmux is not installed")
    subprocess.run([tmux, "new-session", "-d", "-s", session, "-x", str(COLUMNS), "-y", str(ROWS)], check=True)
    try:
        command = (f"cd {work} && clear && {ROOT}/.venv/bin/aerostereo-ingest record --port "
                   f"socket://127.0.0.1:{server.port} --out flight.duml --mission {mission_csv.name}")
        subprocess.run([tmux, "send-keys", "-t", session, command, "Enter"], check=True)
        time.sleep(seconds)
        screen = subprocess.run([tmux, "capture-pane", "-e", "-p", "-t", session], check=True, capture_output=True,
                                text=True).stdout
        subprocess.run([tmux, "send-keys", "-t", session, "C-c", ""], check=True)
        time.sleep(1.0)
    finally:
        subprocess.run([tmux, "kill-session", "-t", session], check=False)
    return screen


def styled_runs(line: str) -> list[tuple[str, bool, bool]]:
    """A line with SGR codes as ``(text, bold, reverse)`` runs."""
    runs, bold, reverse, position = [], False, False, 0
    for match in SGR.finditer(line):
        runs.append((line[position:match.start()], bold, reverse))
        for code in (match.group(1) or "0").split(";"):
            bold = True if code == "1" else False if code in ("0", "22") else bold
            reverse = True if code == "7" else False if code in ("0", "27") else reverse
        position = match.end()
    runs.append((line[position:], bold, reverse))
    return [run for run in runs if run[0]]


def draw(screen: str, out: Path) -> None:
    """``screen`` drawn as a terminal would, into the PNG ``out``."""
    regular = ImageFont.truetype(font_manager.findfont("DejaVu Sans Mono"), FONT_PX)
    bold = ImageFont.truetype(font_manager.findfont("DejaVu Sans Mono:bold"), FONT_PX)
    cell_w, cell_h = regular.getbbox("M")[2], int(FONT_PX * 1.35)
    lines = screen.rstrip("\n").split("\n")
    width = max(len(SGR.sub("", line)) for line in lines) + 2
    image = Image.new("RGB", (width * cell_w, (len(lines) + 1) * cell_h), BACKGROUND)
    pen = ImageDraw.Draw(image)
    for row, line in enumerate(lines):
        column = 1
        for text, is_bold, reverse in styled_runs(line):
            x, y = column * cell_w, (row + 0.5) * cell_h
            colour = FOREGROUND
            if reverse:
                pen.rectangle([x, y, x + len(text) * cell_w, y + cell_h], fill=(200, 60, 50))
                colour = (255, 255, 255)
            pen.text((x, y), text, font=bold if is_bold else regular, fill=colour)
            column += len(text)
    image.save(out, optimize=True)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--out", type=Path, required=True, help="the PNG to write")
    parser.add_argument("--at", type=float, default=10.0, help="seconds after the start to read the screen")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as work:
        screen = screen_text(args.at, Path(work))
    draw(screen, args.out)
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
