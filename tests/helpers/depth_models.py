"""A tiny, randomly initialised Depth Anything model built from a config and saved to a folder (never downloaded)."""

from __future__ import annotations

from pathlib import Path


def build_tiny_depth_anything(d: Path) -> Path:
    import torch
    from transformers import DepthAnythingConfig, DepthAnythingForDepthEstimation, Dinov2Config

    backbone = Dinov2Config(hidden_size=32, num_hidden_layers=2, num_attention_heads=2, intermediate_size=64,
                            image_size=56, patch_size=14, out_features=["stage1", "stage2"], out_indices=[1, 2],
                            reshape_hidden_states=False)
    cfg = DepthAnythingConfig(backbone_config=backbone, reassemble_hidden_size=32, neck_hidden_sizes=[16, 32],
                              reassemble_factors=[2, 1], fusion_hidden_size=16, head_hidden_size=8)
    torch.manual_seed(0)
    model = DepthAnythingForDepthEstimation(cfg).eval()
    with torch.no_grad():  # a random head predicts ~1e-6 everywhere: lift it to a positive, varied disparity
        model.head.conv3.weight.mul_(1e4)
        model.head.conv3.bias.fill_(1.0)
    try:
        from transformers import DPTImageProcessorPil as Proc
    except ImportError:
        from transformers import DPTImageProcessor as Proc
    proc = Proc(do_resize=True, size={"height": 56, "width": 56}, keep_aspect_ratio=False, ensure_multiple_of=14,
                do_normalize=True, image_mean=[0.485, 0.456, 0.406], image_std=[0.229, 0.224, 0.225])
    Path(d).mkdir(parents=True, exist_ok=True)
    model.save_pretrained(d)
    proc.save_pretrained(d)
    return Path(d)
