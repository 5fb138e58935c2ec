"""The binary layout: one table in shm_bridge/layout.py, the same offsets in numpy, in the documented C struct (as
a C compiler lays it out) and in docs/shm-protocol.md; the truth record packs and unpacks without loss."""
from __future__ import annotations

import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

from shm_bridge import layout
from shm_bridge.layout import CONTROL_FIELDS, SLOT_FIELDS, TRUTH_FIELDS, TRUTH_LEN
from shm_bridge.worlds.highway import INDICATORS

DOC = Path(__file__).resolve().parents[2] / "docs" / "shm-protocol.md"


def test_numpy_dtypes_follow_the_field_table():
    for dtype, fields, size in ((layout.CONTROL_DTYPE, CONTROL_FIELDS, layout.CONTROL_SIZE),
                                (layout.SLOT_HEADER_DTYPE, SLOT_FIELDS, layout.SLOT_HEADER_SIZE)):
        assert dtype.itemsize == size
        for f in fields:
            assert dtype.fields[f.name][1] == f.offset
            assert dtype.fields[f.name][0].itemsize == f.size


def test_default_frame_sizes():
    assert layout.slot_size(210 * 280 * 3) == 176704
    assert layout.layout_size(210, 280) == 512 + 2 * 176704
    assert layout.slot_size(1) % layout.SLOT_ALIGN == 0
    assert layout.OFFSET["driver_bell"] % 4 == 0 and layout.OFFSET["world_bell"] % 4 == 0
    # the two sides' fields do not share a cache line
    world = {f.offset // 64 for f in CONTROL_FIELDS if f.writer == "world"}
    driver = {f.offset // 64 for f in CONTROL_FIELDS if f.writer == "driver"}
    assert not world & driver


def test_doc_shows_the_generated_tables_and_c_struct():
    text = DOC.read_text(encoding="utf-8")
    assert layout.render_doc(text) == text, "run: python -m shm_bridge.layout --update docs/shm-protocol.md"
    assert layout.c_header() in text


@pytest.mark.skipif(shutil.which("cc") is None, reason="no C compiler")
def test_c_struct_offsets_match_the_layout(tmp_path):
    """Compile the documented header (its static asserts must hold) and print what the compiler laid out."""
    (tmp_path / "ds_bridge.h").write_text(layout.c_header())
    lines = ['#include <stdio.h>', '#include "ds_bridge.h"', "int main(void) {"]
    for struct, fields in (("ds_control", CONTROL_FIELDS), ("ds_slot", SLOT_FIELDS)):
        lines.append(f'    printf("{struct} sizeof %zu\\n", sizeof({struct}));')
        for f in fields:
            lines.append(f'    printf("{struct} {f.name} %zu %zu\\n", offsetof({struct}, {f.name}), '
                         f"sizeof((({struct} *)0)->{f.name}));")
    lines += ["    return 0;", "}"]
    (tmp_path / "offsets.c").write_text("\n".join(lines) + "\n")
    subprocess.run(["cc", "-std=c11", "-Wall", "-Werror", "-o", "offsets", "offsets.c"], cwd=tmp_path, check=True)
    out = subprocess.run([str(tmp_path / "offsets")], capture_output=True, text=True, check=True).stdout.split("\n")
    seen = {tuple(line.split()[:2]): line.split()[2:] for line in out if line}
    assert seen[("ds_control", "sizeof")] == [str(layout.CONTROL_SIZE)]
    assert seen[("ds_slot", "sizeof")] == [str(layout.SLOT_HEADER_SIZE)]
    for struct, fields in (("ds_control", CONTROL_FIELDS), ("ds_slot", SLOT_FIELDS)):
        for f in fields:
            assert seen[(struct, f.name)] == [str(f.offset), str(f.size)], (struct, f.name)


def _sample() -> dict:
    values = {name: 0.5 + i for i, name in enumerate(INDICATORS)}
    values.update(lanes_left=1, lanes=3, lane_width=3.75, speed=21.5, in_lane=True, on_marking=False,
                  x=-12.25, y=401.0, yaw=-1.25, s=1234.5, d=-1.5, t=73.4, collision=False, off_road=True)
    return values


def test_truth_record_round_trip_through_a_dict():
    values = _sample()
    record = layout.pack_truth(values)
    assert record.shape == (TRUTH_LEN,) and record.dtype == np.float64
    assert list(TRUTH_FIELDS[:14]) == list(INDICATORS)
    back = layout.unpack_truth(record)
    assert list(back) == list(TRUTH_FIELDS)
    assert back == pytest.approx(values)
    assert back["lanes"] == 3 and isinstance(back["lanes"], int)
    assert back["off_road"] is True and back["in_lane"] is True and back["collision"] is False


def test_truth_record_from_arrays():
    values = _sample()
    ind = np.array([values[n] for n in INDICATORS])
    ego = [values[n] for n in layout.EGO_FIELDS]
    record = layout.pack_truth_arrays(ind, ego, lanes_left=1, lanes=3, lane_width=3.75, speed=21.5, in_lane=True,
                                      on_marking=False, t=73.4, off_road=True)
    np.testing.assert_array_equal(record, layout.pack_truth(values))
    np.testing.assert_array_equal(layout.truth_indicators(record), ind)
    np.testing.assert_array_equal(layout.truth_ego(record), ego)


def test_truth_record_refuses_missing_and_unknown_fields():
    values = _sample()
    del values["speed"]
    with pytest.raises(KeyError, match="speed"):
        layout.pack_truth(values)
    assert np.isnan(layout.pack_truth(values, partial=True)[layout.TRUTH_INDEX["speed"]])
    with pytest.raises(KeyError, match="unknown truth field 'sped'"):
        layout.pack_truth(_sample(), sped=3.0)
    with pytest.raises(ValueError, match="shape"):
        layout.check_truth(np.zeros(27))
