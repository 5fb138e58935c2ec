"""The benchmark's files in its output folder: leaderboard.md (also returned), leaderboard.csv, routes.csv,
leaderboard.json and, for scripted scenarios, scenarios.csv (docs/benchmark.md, "Outputs")."""
from __future__ import annotations

from pathlib import Path

from drivestudio.outputs import write_json, write_text
from drivestudio.worlds.highway.benchmark import scenarios
from drivestudio.worlds.highway.benchmark.score import csv_text, markdown, routes_csv_text

BOARD_FILES = ("leaderboard.json", "leaderboard.csv", "routes.csv", "leaderboard.md")
CLIPS = "clips"   # the folder of crash clips


def write_board(out: Path, board: dict) -> str:
    """Write the leaderboard's four files into `out`; returns the Markdown."""
    write_json(out / "leaderboard.json", board)
    write_text(out / "leaderboard.csv", csv_text(board))
    write_text(out / "routes.csv", routes_csv_text(board))
    if scenarios.has_scenarios(board):
        write_text(out / scenarios.SCENARIOS_CSV, scenarios.csv_text(board))
    text = markdown(board)
    write_text(out / "leaderboard.md", text)
    return text
