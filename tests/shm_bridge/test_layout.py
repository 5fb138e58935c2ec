"""The binary layout of protocol version 2: one table of fixed fields in shm_bridge/layout.py, the same offsets in
numpy, in the documented C structs (as a C compiler lays them out) and in docs/shm-protocol.md; the header describes
the world (name, cameras, record names) and reads back into the same layout and declaration."""
from __future__ import annotations

import json
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

from core import worlds
from core.worlds.highway import HIGHWAY, INDICATORS
from shm_bridge import layout
from shm_bridge.layout import ACTION_FIELDS, CAMERA_FIELDS, CONTROL_FIELDS, NAME_FIELDS, SLOT_FIELDS, Layout, layout_for

DOC = Path(__file__).resolve().parents[2] / "docs" / "shm-protocol.md"
STRUCTS = (("ds_control", CONTROL_FIELDS, layout.FIXED_SIZE), ("ds_camera", CAMERA_FIELDS, layout.CAMERA_ENTRY),
           ("ds_name", NAME_FIELDS, layout.NAME_ENTRY), ("ds_slot", SLOT_FIELDS, layout.SLOT_TRUTH),
           ("ds_action", ACTION_FIELDS, layout.ACTION_VALUES))


def test_numpy_dtypes_follow_the_field_tables():
    for dtype, fields, size in ((layout.CONTROL_DTYPE, CONTROL_FIELDS, layout.FIXED_SIZE),
                                (layout.CAMERA_DTYPE, CAMERA_FIELDS, layout.CAMERA_ENTRY),
                                (layout.NAME_DTYPE, NAME_FIELDS, layout.NAME_ENTRY)):
        assert dtype.itemsize == size
        for f in fields:
            assert dtype.fields[f.name][1] == f.offset
            assert dtype.fields[f.name][0].itemsize == f.size


def test_the_sides_fields_keep_to_their_own_cache_lines():
    assert layout.OFFSET["driver_bell"] % 4 == 0 and layout.OFFSET["world_bell"] % 4 == 0
    world = {f.offset // 64 for f in CONTROL_FIELDS if f.writer == "world"}
    driver = {f.offset // 64 for f in CONTROL_FIELDS if f.writer == "driver"}
    either = {f.offset // 64 for f in CONTROL_FIELDS if f.writer == "either"}
    assert not world & driver and not (world | driver) & either


def test_highway_layout_places_one_frame_and_the_records():
    lay = layout_for(HIGHWAY)
    cam = lay.cameras[0]
    assert (cam.name, cam.height, cam.width, cam.channels, cam.size) == ("front", 210, 280, 3, 176400)
    assert lay.slot_header_size == 320 and cam.offset == 320           # 24 + 31 * 8 = 272, rounded up to 64
    assert lay.slot_size == 176768 and lay.layout_size == lay.header_size + 2 * 176768
    assert [n for n, _ in lay.truth] == list(HIGHWAY.truth_names)
    assert [n for n, _ in lay.estimate] == list(INDICATORS) + ["lanes_left", "dist_LB", "dist_RB", "closing_LB",
                                                               "closing_RB"]
    assert [a[0] for a in lay.action] == ["steer", "accel", "brake"]
    assert lay.action_offset % 64 == 0 and lay.header_size % 64 == 0
    assert lay.declaration_offset + len(lay.declaration) <= lay.action_offset


def test_stereo_layout_holds_both_images_of_an_instant():
    decl = worlds.get("sidewalk")
    lay = layout_for(decl)
    left, right = lay.cameras
    assert (left.name, right.name) == ("left", "right")
    assert left.offset == lay.slot_header_size and right.offset >= left.offset + left.size
    assert right.offset % 64 == 0 and lay.slot_size >= right.offset + right.size
    assert lay.modes == ("direct", "follow", "furtive")
    assert len(lay.estimate) == 20 and lay.estimate[9][0] == "steer+10" and lay.estimate[19][0] == "motor+10"


def test_header_reads_back_into_the_same_layout_and_declaration():
    for name in worlds.names():
        decl = worlds.get(name)
        lay = layout_for(decl, lockstep=False)
        buf = np.zeros(lay.header_size, np.uint8)
        lay.write_header(buf)
        back = Layout.read(buf)
        assert back == lay
        assert back.mismatches(buf) == []
        assert back.declaration_object() == decl
        assert json.loads(back.declaration)["name"] == name


def test_a_header_that_contradicts_itself_is_noticed():
    lay = layout_for(HIGHWAY)
    buf = np.zeros(lay.header_size, np.uint8)
    lay.write_header(buf)
    buf[:layout.FIXED_SIZE].view(layout.CONTROL_DTYPE)[0]["slot_size"] += 64
    assert any("slot_size" in m for m in Layout.read(buf).mismatches(buf))


def test_doc_shows_the_generated_tables_and_c_structs():
    text = DOC.read_text(encoding="utf-8")
    assert layout.render_doc(text) == text, "run: python -m shm_bridge.layout --update docs/shm-protocol.md"
    assert layout.c_header() in text


@pytest.mark.skipif(shutil.which("cc") is None, reason="no C compiler")
def test_c_struct_offsets_match_the_layout(tmp_path):
    """Compile the documented header (its static asserts must hold) and print what the compiler laid out."""
    (tmp_path / "ds_bridge.h").write_text(layout.c_header())
    lines = ['#include <stdio.h>', '#include "ds_bridge.h"', "int main(void) {"]
    for struct, fields, _ in STRUCTS:
        lines.append(f'    printf("{struct} sizeof %zu\\n", sizeof({struct}));')
        for f in fields:
            lines.append(f'    printf("{struct} {f.name} %zu %zu\\n", offsetof({struct}, {f.name}), '
                         f"sizeof((({struct} *)0)->{f.name}));")
    lines += ["    return 0;", "}"]
    (tmp_path / "offsets.c").write_text("\n".join(lines) + "\n")
    subprocess.run(["cc", "-std=c11", "-Wall", "-Werror", "-o", "offsets", "offsets.c"], cwd=tmp_path, check=True)
    out = subprocess.run([str(tmp_path / "offsets")], capture_output=True, text=True, check=True).stdout.split("\n")
    seen = {tuple(line.split()[:2]): line.split()[2:] for line in out if line}
    for struct, fields, size in STRUCTS:
        assert seen[(struct, "sizeof")] == [str(size)]
        for f in fields:
            assert seen[(struct, f.name)] == [str(f.offset), str(f.size)], (struct, f.name)


@pytest.mark.skipif(shutil.which("cc") is None, reason="no C compiler")
def test_c_finds_fields_by_name_in_a_real_header(tmp_path):
    """ds_find() of the documented header, over a header written by layout.py: every truth, estimate and action
    name is found at its index, and an unknown name is -1."""
    decl = worlds.get("sidewalk")
    lay = layout_for(decl)
    buf = np.zeros(lay.header_size, np.uint8)
    lay.write_header(buf)
    (tmp_path / "header.bin").write_bytes(buf.tobytes())
    (tmp_path / "ds_bridge.h").write_text(layout.c_header())
    probes = [("DS_TRUTH", n) for n in decl.truth_names] + [("DS_ESTIMATE", "motor+10"),
                                                            ("DS_ACTION", "motor"), ("DS_MODES", "furtive"),
                                                            ("DS_TRUTH", "nonsense")]
    body = "\n".join(f'    printf("%d\\n", ds_find(c, {r}, "{n}"));' for r, n in probes)
    (tmp_path / "find.c").write_text(f"""#include <stdio.h>
#include <stdlib.h>
#include "ds_bridge.h"
int main(void) {{
    static _Alignas(64) uint8_t buf[1 << 20];
    FILE *f = fopen("header.bin", "rb");
    fread(buf, 1, sizeof buf, f);
    fclose(f);
    const ds_control *c = (const ds_control *)buf;
    printf("%.32s %u %u\\n", c->world, ds_cameras(c)[1].height, ds_cameras(c)[1].offset);
{body}
    return 0;
}}
""")
    subprocess.run(["cc", "-std=c11", "-Wall", "-Werror", "-o", "find", "find.c"], cwd=tmp_path, check=True)
    out = subprocess.run(["./find"], cwd=tmp_path, capture_output=True, text=True, check=True).stdout.split("\n")
    right = lay.cameras[1]
    assert out[0] == f"sidewalk {right.height} {right.offset}"
    expected = list(range(len(decl.truth_names))) + [19, 1, 2, -1]
    assert [int(x) for x in out[1:1 + len(probes)]] == expected
