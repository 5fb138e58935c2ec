"""`drivestudio demo --quick`: the main job for both worlds at its smallest, end to end; its report; and every
command of docs/tutorial.md is one the demo runs."""
import re
import subprocess
import sys
from pathlib import Path

import pytest

pytestmark = pytest.mark.slow   # the whole demo at its smallest (about a minute); run with pytest -m slow

REPO = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def demo(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("demo") / "demo"
    r = subprocess.run([sys.executable, "-m", "drivestudio", "demo", "--quick", "--out", str(out)], cwd=REPO,
                       capture_output=True, text=True, timeout=900)
    assert r.returncode == 0, r.stdout[-3000:] + r.stderr[-3000:]
    assert "demo done in" in r.stdout and "== [22/22]" in r.stdout   # progress shown throughout
    return out


def test_the_report_opens_with_the_two_headline_tables(demo):
    text = (demo / "REPORT.md").read_text()
    mae = text.index("## Highway: mean absolute error per indicator")
    autonomy = text.index("## Sidewalk: percentage autonomy")
    assert mae < autonomy < text.index("## Everything else")
    assert re.search(r"\| GIST \+ ridge \| [0-9.]+ \|", text) and re.search(r"\| MobileNet \| [0-9.]+ \|", text)
    assert re.search(r"\| MultiNet \| direct \| [0-9.]+ \|", text) and "| MTL (direct) | direct |" in text
    assert "*paper: AlexNet*" in text and "92.68 / 84.27" in text


def test_every_link_of_the_report_exists(demo):
    text = (demo / "REPORT.md").read_text()
    links = re.findall(r"\]\(([^)]+)\)", text)
    assert len(links) > 20
    for link in links:
        assert (demo / link).exists(), link
    for video in ("highway/oracle-drive.mp4", "sidewalk/expert-furtive.mp4",
                  "sidewalk/autonomy-multinet/autonomy-0.mp4"):
        assert (demo / video).stat().st_size > 10_000


def test_the_highway_test_split_holds_1_2_and_3_lanes(demo):
    from perception.shards import Dataset
    ds = Dataset(demo / "highway" / "data")
    assert sorted({s.params["lanes"] for s in ds.select("test")}) == [1, 2, 3]


def _shape(command: str) -> tuple:
    """A command's verb and options, values reduced to their kind: N (number) or V (anything else)."""
    tokens = command.split()[1:]
    return tuple(t if t.startswith("-") and not re.fullmatch(r"-?[0-9.e-]+", t) else
                 ("N" if re.fullmatch(r"-?[0-9.e-]+", t) else "V") for t in tokens)


def test_every_tutorial_command_is_one_the_demo_runs(demo):
    ran = {_shape(line) for line in (demo / "commands.txt").read_text().splitlines() if line}
    tutorial = (REPO / "docs" / "tutorial.md").read_text()
    commands = [line.strip() for block in re.findall(r"```sh\n(.*?)```", tutorial, re.S)
                for line in block.splitlines() if line.strip().startswith("drivestudio ")]
    assert len(commands) >= 18
    for command in commands:
        if command.startswith("drivestudio --help"):
            continue
        assert _shape(command) in ran, command
