"""The one driver spec (drivestudio/driver_spec.py): `NAME_OR_CKPT[@filter=value,...]`, read alike by drive,
benchmark, the studio, aggregate and the recipes."""
import pytest

from drivestudio.driver_spec import DriverSpec, parse_driver
from drivestudio.errors import UsageError
from drivestudio.worlds.highway.filters import FILTERS
from drivestudio.worlds.highway.plugin import Plugin as Highway
from drivestudio.worlds.sidewalk.plugin import Plugin as Sidewalk

EXACT = ("oracle", "oracle-extended")


def highway(text: str) -> DriverSpec:
    return parse_driver(text, FILTERS, EXACT)


def test_a_name_or_a_checkpoint_alone_has_no_filters():
    assert highway("oracle") == DriverSpec("oracle")
    assert highway("runs/a.pt") == DriverSpec("runs/a.pt")


def test_filters_follow_the_at_sign_as_name_value_pairs():
    assert highway("runs/a.pt@smoothing=0.5").filters == (("smoothing", 0.5),)
    assert highway("runs/a.pt@pass_memory=10").get("pass_memory") == 10.0   # seconds, not a factor
    assert highway("runs/a.pt@pass_memory=15,rear_memory=10").filters == (("pass_memory", 15.0),
                                                                         ("rear_memory", 10.0))


def test_filters_are_put_in_the_worlds_order_so_one_driver_has_one_spec():
    a, b = highway("runs/a.pt@gap_hold=0.8,smoothing=0.3"), highway("runs/a.pt@smoothing=0.3,gap_hold=0.8")
    assert a == b and a.filters == (("smoothing", 0.3), ("gap_hold", 0.8))


def test_a_filter_at_zero_is_no_filter():
    assert highway("runs/a.pt@smoothing=0") == highway("runs/a.pt")


def test_the_spec_reads_back_from_its_text():
    for text in ("oracle", "runs/a.pt@smoothing=0.5,gap_hold=0.8", "runs/a.pt@pass_memory=15,rear_memory=10"):
        assert highway(str(highway(text))) == highway(text)


def test_a_file_whose_name_holds_an_at_sign_is_a_file(tmp_path):
    f = tmp_path / "net@2.pt"
    f.write_bytes(b"x")
    assert highway(str(f)) == DriverSpec(str(f))


@pytest.mark.parametrize("bad, why", [
    ("runs/a.pt@smoothing=2", "smoothing must be a number from 0 to 0.95"),
    ("runs/a.pt@smoothing=nan", "smoothing must be a number"),
    ("runs/a.pt@gap_hold=1", "gap_hold must be a number from 0 to 0.95"),
    ("runs/a.pt@pass_memory=61", "pass_memory must be a number from 0 to 60 s"),
    ("runs/a.pt@pass_memory=-1", "pass_memory must be a number"),
    ("runs/a.pt@rear_memory=61", "rear_memory must be a number from 0 to 60 s"),
    ("runs/a.pt@speed=1", "unknown filter 'speed'"),
    ("runs/a.pt@smoothing", "filters as name=value"),
    ("runs/a.pt@smoothing=0.1,smoothing=0.2", "smoothing is given twice"),
    ("oracle@smoothing=0.5", "oracle reads the exact labels"),
    ("oracle-extended@rear_memory=10", "oracle-extended reads the exact labels"),
    ("@smoothing=0.5", "no driver before '@'"),
    (" ", "empty"),
])
def test_bad_specs_are_refused_in_one_line(bad, why):
    with pytest.raises(UsageError, match=why) as e:
        highway(bad)
    assert "\n" not in str(e.value)


def test_the_syntax_alone_is_checked_before_the_world_is_known():
    """`drive --shm` reads its world from the bridge's header: until then only the syntax can be checked."""
    assert parse_driver("runs/a.pt@anything=3").filters == (("anything", 3.0),)
    with pytest.raises(UsageError):
        parse_driver("runs/a.pt@anything")


def test_each_world_checks_its_own_filters():
    assert Highway().parse_driver("runs/a.pt@smoothing=0.5").get("smoothing") == 0.5
    with pytest.raises(UsageError, match="this world's drivers take none"):
        Sidewalk().parse_driver("runs/z.pt@smoothing=0.5")
