"""Make one checkpoint of several trained regressors of a world (perception/ensemble.py): each reads the same
frames, the closest gap any of them reads is believed, every other output is their mean.

    drivestudio ensemble --out runs/ensemble.pt runs/a.pt runs/b.pt [--gaps mean]

The members must read the same input (camera, size, earlier frames, frame inset) of one world; each keeps its own
input statistics. They may estimate different outputs: the ensemble estimates the union, each output combined over
the members that estimate it (networks of the paper's 13 with one that learned only the cars beside and behind).
The result drives, benchmarks, evaluates and exports as any checkpoint. Bad input is refused in one line (exit
status 2) before anything is written.
"""
from __future__ import annotations

import copy

from perception.checkpoint import CheckpointError
from perception.ensemble import GAP_PREFIX
from perception.models import Regressor, add_renderers, declaration_of, family_title, load_model

SAME_INPUT = ("channels", "height", "width", "instants", "cameras", "scaling", "inset")


def union(lists: list[list[str]], order: tuple[str, ...]) -> list[str]:
    """The names of every list, in the world's declared order."""
    have = {n for names in lists for n in names}
    return [n for n in order if n in have]


def make(paths: list[str], combine: str = "min") -> dict:
    """The ensemble's checkpoint payload (spec and weights) from the members' checkpoint files."""
    if len(paths) < 2:
        raise CheckpointError("an ensemble needs at least two checkpoints")
    if len(set(paths)) != len(paths):
        raise CheckpointError("a checkpoint is given twice")
    nets = [load_model(p)[0] for p in paths]
    first = nets[0].spec
    for path, net in zip(paths, nets):
        spec = net.spec
        if spec["name"] == "ensemble":
            raise CheckpointError(f"{path} is an ensemble already; give its members")
        if spec["input"].get("scaling") != "standardise":
            raise CheckpointError(f"{path}: a {spec['name']} model scales its input otherwise; an ensemble "
                                  "combines standardising regressors")
        if spec["world"] != first["world"]:
            raise CheckpointError(f"{path} is a model of the {spec['world']} world, {paths[0]} of the "
                                  f"{first['world']} world")
        differ = [k for k in SAME_INPUT if spec["input"].get(k) != first["input"].get(k)]
        if differ:
            raise CheckpointError(f"{path} reads another input than {paths[0]} ({', '.join(differ)} differ)")
    spec = copy.deepcopy(first)
    c = int(spec["input"]["channels"])
    spec["name"] = "ensemble"
    add_renderers(spec, {r for n in nets for r in n.spec["input"].get("renderers", ())})
    spec["input"].update(mean=[0.0] * c, std=[1.0] * c)
    decl = declaration_of(first)
    spec["labels"] = union([n.spec["labels"] for n in nets], decl.label_names)
    spec["outputs"] = union([n.spec["outputs"] for n in nets], decl.outputs(decl.label_names))
    spec["normalisation"] = decl.normalisation(spec["outputs"])
    members = []
    for p, n in zip(paths, nets):
        members.append({"name": n.spec["name"], "options": n.spec.get("options", {}), "mean": n.spec["input"]["mean"],
                        "std": n.spec["input"]["std"], "title": family_title(n.spec), "source": str(p)})
        if n.spec["outputs"] != spec["outputs"]:   # a member of fewer outputs (perception/ensemble.py)
            members[-1]["estimates"] = [spec["outputs"].index(o) for o in n.spec["outputs"]]
    spec["options"] = {"members": members, "combine": combine,
                       "gaps": [i for i, o in enumerate(spec["outputs"]) if o.startswith(GAP_PREFIX)]}
    model = Regressor(spec)
    for member, net in zip(model.net.get_submodule("members").children(), nets):
        member.load_state_dict(net.net.state_dict())
    return {"spec": spec, "state_dict": model.state_dict()}
