"""drivestudio export --model CKPT --onnx out.onnx: a trained model as ONNX, checked against PyTorch."""
from __future__ import annotations

from core.files import check_output
from drivestudio.checkpoints import check_checkpoint_path

TOLERANCE = 1e-4   # largest |ONNX Runtime - PyTorch| accepted, in the labels' units


def register(sub) -> None:
    p = sub.add_parser("export", help="export a trained model to ONNX (checked by running it)",
                       description="Write the model of a checkpoint as an ONNX graph that takes uint8 images "
                                   "(batch, channels, height, width) and int64 behavioural modes (batch,) and returns "
                                   "the outputs in the labels' units; then run it with ONNX Runtime and compare with "
                                   "PyTorch: the file is written only when they agree. Prints the parameter count "
                                   "and the size in MB.")
    p.add_argument("--model", required=True, help="checkpoint written by `drivestudio train`")
    p.add_argument("--onnx", required=True, help="the .onnx file to write")
    p.set_defaults(func=run)


def run(args) -> int:
    from perception.export import export_onnx  # lazy: torch

    check_checkpoint_path(args.model)
    check_output(args.onnx, (".onnx",), "ONNX file")
    r = export_onnx(args.model, args.onnx)
    print(f"wrote {r['onnx']}: {r['parameters']:,} parameters, {r['float32_mb']:.2f} MB of float32 weights, "
          f"{r['bytes'] / 1e6:.2f} MB file; inputs images {r['inputs']['images']} uint8 and modes int64; "
          f"{len(r['outputs'])} outputs")
    print(f"ONNX Runtime vs PyTorch on 4 random samples: largest difference {r['max_abs_difference']:.2e}")
    return 0
