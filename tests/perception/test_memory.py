"""The batch-size bound (perception/memory.py): a batch whose inputs alone (9 bytes per value: uint8 read, float32
scaled, float32 normalised) exceed half of the available memory is refused, naming the largest that fits."""
import pytest

from perception.memory import BatchTooLarge, available_memory, batch_input_bytes, check_batch

ALEXNET = {"channels": 3, "height": 210, "width": 280}   # 176,400 values: 1,587,600 bytes a sample


def test_the_bound_is_half_the_available_memory_over_nine_bytes_a_value():
    assert batch_input_bytes(1, ALEXNET) == 3 * 210 * 280 * 9 == 1_587_600
    gib = 2**30
    most = int(0.5 * gib // 1_587_600)                   # 338 samples in half a GiB
    check_batch(most, ALEXNET, available=gib)             # fits exactly
    with pytest.raises(BatchTooLarge, match=f"--batch-size {most + 1}: .* at most {most} fits"):
        check_batch(most + 1, ALEXNET, available=gib)


def test_the_machine_s_available_memory_is_read():
    assert 2**26 < available_memory() < 2**44            # between 64 MiB and 16 TiB
