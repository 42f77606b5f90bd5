"""Export torchvision's Mask R-CNN (ResNet-50 FPN) to ONNX in the contract DensePeds reads.

    pip install 'densepeds[export]'          # torch + torchvision (not needed at run time)
    python models/export_maskrcnn.py [--weights coco|random] [--out maskrcnn_resnet50_fpn.onnx]

--weights coco downloads torchvision's COCO weights (the only step that uses the network, run by
you, once); --weights random exports the architecture untrained (for testing the contract).
Contract: input "image" float32 [3, H, W] RGB in [0, 1]; outputs "boxes" [N, 4] (x1, y1, x2, y2
pixels), "labels" int64 [N] (COCO ids, person = 1), "scores" [N], "masks" [N, 1, H, W]
probabilities. Exported with opset 17 and the TorchScript exporter (dynamo=False: the dynamo
exporter fails on this model). Put the file in $DENSEPEDS_MODEL_DIR or ~/.cache/densepeds/models.
"""

from __future__ import annotations

import argparse
from pathlib import Path


def export(out: Path, weights: str, height: int, width: int, check: bool) -> None:
    import torch
    import torchvision

    chosen = "DEFAULT" if weights == "coco" else None
    model = torchvision.models.detection.maskrcnn_resnet50_fpn(
        weights=chosen, weights_backbone=None
    )
    model.eval()
    image = torch.rand(3, height, width)
    torch.onnx.export(
        model,
        ([image],),
        str(out),
        opset_version=17,
        dynamo=False,
        input_names=["image"],
        output_names=["boxes", "labels", "scores", "masks"],
        dynamic_axes={
            "image": {1: "height", 2: "width"},
            "boxes": {0: "detections"},
            "labels": {0: "detections"},
            "scores": {0: "detections"},
            "masks": {0: "detections", 2: "height", 3: "width"},
        },
    )
    print(f"wrote {out} ({out.stat().st_size / 1e6:.0f} MB)")
    if check:
        import numpy as np
        import onnxruntime as ort

        session = ort.InferenceSession(str(out), providers=["CPUExecutionProvider"])
        got = session.run(None, {"image": image.numpy()})
        with torch.no_grad():
            want = model([image])[0]
        for name, value in zip(("boxes", "labels", "scores", "masks"), got, strict=True):
            np.testing.assert_allclose(value, want[name].numpy(), rtol=1e-3, atol=1e-4)
        print(f"onnxruntime matches torch on a random {height}x{width} image")


def main() -> None:
    parser = argparse.ArgumentParser(description="Export Mask R-CNN to ONNX for DensePeds")
    parser.add_argument("--out", type=Path, default=Path("maskrcnn_resnet50_fpn.onnx"))
    parser.add_argument("--weights", choices=("coco", "random"), default="coco")
    parser.add_argument("--height", type=int, default=540)
    parser.add_argument("--width", type=int, default=960)
    parser.add_argument("--no-check", action="store_true", help="skip the onnxruntime check")
    args = parser.parse_args()
    export(args.out, args.weights, args.height, args.width, not args.no_check)


if __name__ == "__main__":
    main()
