"""The studio's WebSocket messages (docs/studio.md): every malformed message is refused with one line that says what
is wrong; the frame message round-trips."""
from __future__ import annotations

import json

import pytest

from drivestudio.studio.protocol import MAX_MESSAGE, ProtocolError, pack_frame, parse, unpack_frame


@pytest.mark.parametrize("text, says", [
    ("not json", "not JSON"),
    ("[1, 2]", "a JSON object with a 'type'"),
    ('{"kind": "pause"}', "unknown message type None"),
    ('{"type": "explode"}', "unknown message type 'explode'"),
    ('{"type": "pause", "now": true}', "unknown field 'now'"),
    ('{"type": "ack"}', "missing 'seq'"),
    ('{"type": "ack", "seq": -1}', "'seq' must be an integer from 0"),
    ('{"type": "ack", "seq": 1.5}', "'seq' must be an integer"),
    ('{"type": "pace", "realtime": "yes"}', "'realtime' must be true or false"),
    ('{"type": "driver", "name": "../../etc/passwd"}', "'name' must be the name of a driver"),
    ('{"type": "driver", "name": "/tmp/model.pt"}', "'name' must be the name of a driver"),
    ('{"type": "record", "on": true, "name": "../outside"}', "'name' must be a name of letters"),
    ('{"type": "record", "on": true, "name": "a/b"}', "'name' must be a name of letters"),
    ('{"type": "record"}', "'on' must be true or false"),
    ('{"type": "reset", "seed": 1e40}', "'seed' must be an integer"),
    ('{"type": "reset", "seed": 4294967296}', "'seed' must be an integer from 0 to 4294967295"),
    ('{"type": "reset", "track": "/home/x/track.json"}', "'track' must be a preset track name or procedural"),
    ('{"type": "input", "keys": {"left": 1}}', "'left' must be true or false"),
    ('{"type": "input", "keys": {"jump": true}}', "unknown field 'jump'"),
    ('{"type": "input", "keys": [], "gamepad": null}', "'keys' must be an object"),
    ('{"type": "input", "gamepad": {"steer": 2}}', "'steer' must be a number from -1 to 1"),
    ('{"type": "input", "gamepad": {"throttle": NaN}}', "not JSON"),
    ('{"type": "input", "gamepad": {"throttle": -0.5}}', "'throttle' must be a number from 0 to 1"),
    ('{"type": "input", "gamepad": "fast"}', "'gamepad' must be an object"),
])
def test_a_malformed_message_is_refused_with_one_line_naming_what_is_wrong(text, says):
    with pytest.raises(ProtocolError) as err:
        parse(text)
    assert says in str(err.value)
    assert "\n" not in str(err.value)


def test_too_long_and_binary_messages_are_refused():
    with pytest.raises(ProtocolError, match="too long"):
        parse(json.dumps({"type": "pause", "x": "a" * MAX_MESSAGE}))
    with pytest.raises(ProtocolError, match="not binary"):
        parse(b'{"type": "pause"}')
    with pytest.raises(ProtocolError, match="not JSON"):
        parse("[" * 2000 + "]" * 2000)           # deep, but short: still not a message


def test_well_formed_messages_parse_to_their_fields():
    assert parse('{"type": "pause"}').type == "pause"
    assert parse('{"type": "ack", "seq": 7}').fields == {"seq": 7}
    assert parse('{"type": "reset", "seed": 3, "track": "procedural:12"}').fields == {"seed": 3,
                                                                                      "track": "procedural:12"}
    assert parse('{"type": "record", "on": true, "name": "demo-1"}').fields == {"on": True, "name": "demo-1"}
    m = parse('{"type": "input", "keys": {"left": true, "up": false}, "gamepad": {"steer": -0.5}}')
    assert m.fields == {"keys": {"left": True, "up": False},
                        "gamepad": {"steer": -0.5, "throttle": 0.0, "brake": 0.0}}
    assert parse('{"type": "input", "keys": {}, "gamepad": null}').fields == {"keys": {}}


def test_who_may_send_what():
    assert parse('{"type": "ack", "seq": 1}').who == "any"
    assert parse('{"type": "pause"}').who == "view"        # also a --view ...,control page
    assert parse('{"type": "driver", "name": "oracle"}').who == "wheel"


def test_a_frame_message_round_trips():
    state = {"seq": 3, "t": 1.5, "command": [0.1, None]}
    data = pack_frame(state, [("left", b"\xff\xd8abc", 336, 188), ("topdown", b"\xff\xd8defg", 240, 240)])
    back, images = unpack_frame(data)
    assert back["seq"] == 3 and back["command"] == [0.1, None]
    assert [i["name"] for i in back["images"]] == ["left", "topdown"]
    assert images == {"left": b"\xff\xd8abc", "topdown": b"\xff\xd8defg"}
    with pytest.raises(ValueError):
        pack_frame({"t": float("nan")}, [])      # the page reads strict JSON
