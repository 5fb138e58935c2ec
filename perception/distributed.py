"""Several training processes (`torchrun --nproc_per_node N -m drivestudio train ...`): this process's place in
the run (torchrun's RANK, WORLD_SIZE and LOCAL_RANK), the process group (gloo on the CPU, nccl on CUDA, one GPU
per process) and the collectives the SGD loop needs (docs/scaling.md)."""
from __future__ import annotations

import os
from dataclasses import dataclass

import torch

from perception.training import TrainingError


@dataclass
class Distributed:
    """This process's place in a torchrun run; rank 0 of a world of 1 when there is none."""

    rank: int = 0
    world_size: int = 1
    local_rank: int = 0
    initialised_here: bool = False
    device: torch.device = torch.device("cpu")   # where collectives' tensors live (nccl: this rank's GPU)

    @property
    def active(self) -> bool:
        return self.world_size > 1

    @property
    def main(self) -> bool:
        return self.rank == 0

    def barrier(self) -> None:
        if self.active:
            torch.distributed.barrier()

    def mean(self, values: list[float]) -> list[float]:
        """The mean over ranks of each value (every rank calls it at the same point)."""
        if not self.active:
            return list(values)
        t = torch.tensor(values, dtype=torch.float64, device=self.device)
        torch.distributed.all_reduce(t)
        return (t / self.world_size).cpu().tolist()

    def minimum(self, value: int) -> int:
        if not self.active:
            return value
        t = torch.tensor([value], dtype=torch.int64, device=self.device)
        torch.distributed.all_reduce(t, op=torch.distributed.ReduceOp.MIN)
        return int(t.item())

    def share(self, obj):
        """Rank 0's `obj` on every rank."""
        if not self.active:
            return obj
        box = [obj]
        torch.distributed.broadcast_object_list(box, src=0)
        return box[0]

    def close(self) -> None:
        if self.initialised_here and torch.distributed.is_initialized():
            torch.distributed.destroy_process_group()


def distributed_env() -> tuple[int, int, int] | None:
    """(rank, world size, local rank) from torchrun's environment, or None for a single process."""
    try:
        world = int(os.environ.get("WORLD_SIZE", "1"))
        if world <= 1 or "RANK" not in os.environ:
            return None
        return int(os.environ["RANK"]), world, int(os.environ.get("LOCAL_RANK", "0"))
    except ValueError:
        raise TrainingError("RANK, WORLD_SIZE and LOCAL_RANK must be integers (as torchrun sets them)") from None


def join_distributed(device: torch.device) -> tuple[Distributed, torch.device]:
    """Join torchrun's process group when launched by it (gloo on the CPU, nccl on CUDA; each process on the GPU
    of its LOCAL_RANK unless a device index was given)."""
    env = distributed_env()
    if env is None:
        return Distributed(), device
    rank, world, local = env
    if device.type == "cuda" and device.index is None:
        device = torch.device("cuda", local)
    if device.type == "cuda":
        torch.cuda.set_device(device)
    here = not torch.distributed.is_initialized()
    if here:
        torch.distributed.init_process_group("nccl" if device.type == "cuda" else "gloo", rank=rank,
                                             world_size=world)
    return Distributed(rank, world, local, here, device if device.type == "cuda" else torch.device("cpu")), device
