"""The behavioural mode is a shared flag of the bridge: a driver process switches it while driving, the world
switches at that step, and the driving changes (furtive drives slower than direct; the record says which mode)."""
import json
import os
import subprocess
import sys
import uuid
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]

DRIVER = r"""
import sys, json
import numpy as np
from shm_bridge.endpoints import DriverEndpoint
from controller.sidewalk import SidewalkExpert
expert = SidewalkExpert()
speeds = {"direct": [], "furtive": []}
i_speed, i_mode = None, None
with DriverEndpoint(sys.argv[1], attach_timeout=60) as ep:
    decl = ep.declaration
    i_speed, i_mode = decl.index("speed"), decl.index("behaviour")
    n = 0
    while (msg := ep.wait_frame()) is not None:
        mode = decl.modes[int(msg.record[i_mode])]
        if mode in speeds and n >= 1:
            speeds[mode].append(float(msg.record[i_speed]))
        if n == 240:                 # 8 s in: from direct to furtive, through the shared flag
            ep.behaviour = "furtive"
        ep.send_action(msg.seq, expert.action(msg.record))
        n += 1
print(json.dumps({k: [len(v), float(np.mean(v[-60:])) if v else None] for k, v in speeds.items()}))
"""


def test_switching_the_mode_over_the_bridge_changes_the_driving(tmp_path):
    name = f"dstest-mode-{uuid.uuid4().hex[:8]}"
    serve = subprocess.Popen([sys.executable, "-m", "drivestudio", "serve", "--world", "sidewalk", "--shm", name,
                              "--path", "park", "--mode", "direct", "--seconds", "16", "--out", str(tmp_path)],
                             cwd=REPO, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    driver = subprocess.run([sys.executable, "-c", DRIVER, name], cwd=REPO, capture_output=True, text=True,
                            timeout=300)
    out, err = serve.communicate(timeout=300)
    assert serve.returncode == 0, err
    assert driver.returncode == 0, driver.stderr
    seen = json.loads(driver.stdout)
    direct, furtive = seen["direct"], seen["furtive"]
    assert direct[0] > 200 and furtive[0] > 200            # both modes were driven, around the switch at 8 s
    assert furtive[1] < 0.8 * direct[1]                     # furtive creeps along its border: visibly slower
    metrics = json.loads((tmp_path / "metrics.json").read_text())
    assert metrics["mode_share"]["direct"] > 0.4 and metrics["mode_share"]["furtive"] > 0.4
    assert not os.path.exists(f"/dev/shm/{name}")
