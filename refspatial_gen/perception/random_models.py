"""Randomly initialised models of every family, saved like published checkpoints (tests, demos, benches).

Nothing is downloaded: each model is built from its transformers config (`tiny`: a few thousand
parameters, for tests; `full`: the published architecture's default sizes, for speed figures), its
processor from the same settings the published folder uses, and its tokenizer from a small word list
(BERT word pieces for Grounding DINO and BLIP, byte-level BPE for CLIP/OWLv2, a trained SentencePiece
model for SigLIP). Folder names follow the published checkpoints (docs/perception.md), and every folder
holds `RANDOM_WEIGHTS.txt`: random models detect random boxes, which is what plumbing tests need.
"""

from __future__ import annotations

from pathlib import Path
from typing import Callable

from refspatial_gen.perception.vocab import COCO_THINGS

FOLDERS = {
    "grounding-dino": "grounding-dino-tiny", "owlv2": "owlv2-base-patch16-ensemble", "sam": "sam-vit-base",
    "sam2": "sam2.1-hiera-tiny", "depth-anything": "depth-anything-v2-metric-indoor-small", "depth-pro": "depth-pro",
    "zoedepth": "zoedepth-nyu-kitti", "clip": "clip-vit-base-patch32", "siglip": "siglip-base-patch16-224",
    "vlm": "blip-image-captioning-base",
}
# family -> (folder, the published checkpoint to place there, its licence)
CHECKPOINTS = {
    "grounding-dino": (FOLDERS["grounding-dino"], "IDEA-Research/grounding-dino-tiny (or -base)", "Apache-2.0"),
    "owlv2": (FOLDERS["owlv2"], "google/owlv2-base-patch16-ensemble (or -large-)", "Apache-2.0"),
    "sam": (FOLDERS["sam"], "facebook/sam-vit-base (or -large, -huge)", "Apache-2.0"),
    "sam2": (FOLDERS["sam2"], "facebook/sam2.1-hiera-tiny (or -small, -base-plus, -large)", "Apache-2.0"),
    "depth-anything": (FOLDERS["depth-anything"], "depth-anything/Depth-Anything-V2-Metric-Indoor-Small-hf "
                       "(Outdoor: a second folder)", "Apache-2.0 (Small); Base/Large: CC-BY-NC-4.0"),
    "depth-pro": (FOLDERS["depth-pro"], "apple/DepthPro-hf", "Apple ML Research (apple-amlr)"),
    "zoedepth": (FOLDERS["zoedepth"], "Intel/zoedepth-nyu-kitti (or -nyu, -kitti)", "MIT"),
    "clip": (FOLDERS["clip"], "openai/clip-vit-base-patch32 (or -large-patch14)", "MIT"),
    "siglip": (FOLDERS["siglip"], "google/siglip-base-patch16-224 (needs sentencepiece)", "Apache-2.0"),
    "vlm": (FOLDERS["vlm"], "Salesforce/blip-image-captioning-base, or HuggingFaceTB/SmolVLM-256M-Instruct "
            "(any image-text-to-text model)", "BSD-3-Clause / Apache-2.0"),
}
WORDS = sorted({w for n in COCO_THINGS for w in n.split()} | set(
    "a an the photo of picture made wooden metal plastic glass ceramic fabric paper leather blurry dark bright "
    "indoor outdoor room table scene with objects screenshot text document cartoon drawing describe in few words "
    "cup mug chair person".split()))
CHARS = [chr(c) for c in range(97, 123)] + list("0123456789.,()'-")


def _bert_tokenizer():
    from transformers import BertTokenizer

    toks = ["[PAD]", "[UNK]", "[CLS]", "[SEP]", "[MASK]", "[DEC]"] + CHARS + [f"##{c}" for c in CHARS] + WORDS
    vocab = {t: i for i, t in enumerate(dict.fromkeys(toks))}
    return BertTokenizer(vocab=vocab), len(vocab)


def _clip_tokenizer():
    from transformers import CLIPTokenizer

    vocab: dict[str, int] = {}
    for t in ["!", "<|startoftext|>", "<|endoftext|>"] + CHARS + [c + "</w>" for c in CHARS]:
        vocab.setdefault(t, len(vocab))
    merges: list[tuple[str, str]] = []
    for w in WORDS:
        parts = list(w[:-1]) + [w[-1] + "</w>"]
        while len(parts) > 1:
            pair = (parts[0], parts[1])
            if pair not in merges:
                merges.append(pair)
            vocab.setdefault(parts[0] + parts[1], len(vocab))
            parts = [parts[0] + parts[1]] + parts[2:]
    return CLIPTokenizer(vocab=vocab, merges=merges), len(vocab)


def _spm_tokenizer(work: Path):
    import sentencepiece as spm
    from transformers import SiglipTokenizer

    corpus = work / "spm_corpus.txt"
    corpus.write_text("\n".join(" ".join(WORDS[i:] + WORDS[:i]) for i in range(0, len(WORDS), 3)), encoding="utf-8")
    spm.SentencePieceTrainer.train(input=str(corpus), model_prefix=str(work / "spm"), vocab_size=96,
                                   model_type="unigram", pad_id=0, eos_id=1, unk_id=2, bos_id=-1,
                                   hard_vocab_limit=False, minloglevel=2)
    tok = SiglipTokenizer(vocab_file=str(work / "spm.model"))
    return tok, tok.vocab_size


def _save(model, processor, out: Path) -> Path:
    out.mkdir(parents=True, exist_ok=True)
    model.save_pretrained(out)
    if processor is not None:
        processor.save_pretrained(out)
    (out / "RANDOM_WEIGHTS.txt").write_text("Randomly initialised weights (refspatial_gen.perception.random_models): "
                                            "for tests and speed benches only.\n", encoding="utf-8")
    return out


def grounding_dino(out: Path, full: bool) -> Path:
    from transformers import (GroundingDinoConfig, GroundingDinoForObjectDetection, GroundingDinoImageProcessorPil,
                              GroundingDinoProcessor)

    tok, n = _bert_tokenizer()
    if full:
        cfg = GroundingDinoConfig(text_config={"model_type": "bert", "vocab_size": max(n, 30522)})
        ip = GroundingDinoImageProcessorPil()
    else:
        cfg = GroundingDinoConfig(
            backbone_config={"model_type": "swin", "embed_dim": 16, "depths": [1, 1, 1, 1], "num_heads": [1, 1, 1, 1],
                             "window_size": 4, "image_size": 64, "out_indices": [2, 3, 4]},
            text_config={"model_type": "bert", "vocab_size": n, "hidden_size": 32, "num_hidden_layers": 1,
                         "num_attention_heads": 2, "intermediate_size": 37, "max_position_embeddings": 128},
            d_model=32, encoder_layers=1, decoder_layers=2, encoder_ffn_dim=32, decoder_ffn_dim=32,
            encoder_attention_heads=2, decoder_attention_heads=2, num_queries=30, max_text_len=128)
        # >= 128 px: the fifth feature level (stride 64) keeps at least 2 x 2 cells, which group norm needs
        ip = GroundingDinoImageProcessorPil(size={"shortest_edge": 128, "longest_edge": 256})
    return _save(GroundingDinoForObjectDetection(cfg).eval(), GroundingDinoProcessor(image_processor=ip, tokenizer=tok), out)


def owlv2(out: Path, full: bool) -> Path:
    from transformers import Owlv2Config, Owlv2ForObjectDetection, Owlv2ImageProcessorPil, Owlv2Processor

    tok, n = _clip_tokenizer()
    ids = {"bos_token_id": 1, "eos_token_id": 2, "pad_token_id": 2}
    if full:
        cfg = Owlv2Config(text_config={"vocab_size": max(n, 49408), **ids})
        ip = Owlv2ImageProcessorPil()
    else:
        cfg = Owlv2Config(text_config=dict(vocab_size=n, hidden_size=32, intermediate_size=37, num_hidden_layers=1,
                                           num_attention_heads=2, max_position_embeddings=16, **ids),
                          vision_config=dict(hidden_size=32, intermediate_size=37, num_hidden_layers=1,
                                             num_attention_heads=2, image_size=64, patch_size=16), projection_dim=32)
        ip = Owlv2ImageProcessorPil(size={"height": 64, "width": 64})
    return _save(Owlv2ForObjectDetection(cfg).eval(), Owlv2Processor(image_processor=ip, tokenizer=tok), out)


def sam(out: Path, full: bool) -> Path:
    from transformers import SamConfig, SamImageProcessorPil, SamModel, SamProcessor

    if full:
        cfg, ip = SamConfig(), SamImageProcessorPil()
    else:
        cfg = SamConfig(
            vision_config=dict(hidden_size=32, num_hidden_layers=1, num_attention_heads=2, intermediate_size=37,
                               image_size=64, patch_size=16, output_channels=16, window_size=2,
                               global_attn_indexes=[0], mlp_dim=37, num_pos_feats=8),
            prompt_encoder_config=dict(hidden_size=16, image_size=64, patch_size=16, mask_input_channels=4),
            mask_decoder_config=dict(hidden_size=16, mlp_dim=32, num_hidden_layers=2, num_attention_heads=2,
                                     iou_head_hidden_dim=16))
        ip = SamImageProcessorPil(size={"longest_edge": 64}, pad_size={"height": 64, "width": 64},
                                  mask_size={"longest_edge": 16}, mask_pad_size={"height": 16, "width": 16})
    return _save(SamModel(cfg).eval(), SamProcessor(image_processor=ip), out)


def sam2(out: Path, full: bool) -> Path:
    import json

    from transformers import Sam2Config, Sam2Model

    size = 1024
    if full:
        cfg = Sam2Config()
    else:
        size = 64
        cfg = Sam2Config(
            vision_config=dict(
                backbone_config=dict(model_type="sam2_hiera_det_model", hidden_size=8, image_size=[64, 64],
                                     blocks_per_stage=[1, 1, 2, 1], embed_dim_per_stage=[8, 16, 32, 64],
                                     num_attention_heads_per_stage=[1, 1, 1, 1], window_size_per_stage=[4, 4, 4, 4],
                                     global_attention_blocks=[3], window_positional_embedding_background_size=[2, 2]),
                backbone_channel_list=[64, 32, 16, 8], backbone_feature_sizes=[[16, 16], [8, 8], [4, 4]], fpn_hidden_size=16),
            prompt_encoder_config=dict(hidden_size=16, image_size=64, patch_size=16, mask_input_channels=4),
            mask_decoder_config=dict(hidden_size=16, mlp_dim=32, num_hidden_layers=2, num_attention_heads=2,
                                     iou_head_hidden_dim=16))
    path = _save(Sam2Model(cfg).eval(), None, out)
    (path / "preprocessor_config.json").write_text(json.dumps(
        {"image_processor_type": "Sam2ImageProcessor", "size": {"height": size, "width": size},
         "image_mean": [0.485, 0.456, 0.406], "image_std": [0.229, 0.224, 0.225], "rescale_factor": 1 / 255}), "utf-8")
    return path


def depth_anything(out: Path, full: bool) -> Path:
    from transformers import DepthAnythingConfig, DepthAnythingForDepthEstimation, DPTImageProcessorPil

    if full:  # Depth-Anything-V2-Metric-Indoor-Small: DINOv2 ViT-S/14 backbone
        cfg = DepthAnythingConfig(
            backbone_config=dict(model_type="dinov2", hidden_size=384, num_hidden_layers=12, num_attention_heads=6,
                                 intermediate_size=1536, patch_size=14, image_size=518,
                                 out_indices=[3, 6, 9, 12], reshape_hidden_states=False),
            reassemble_hidden_size=384, neck_hidden_sizes=[48, 96, 192, 384], fusion_hidden_size=64,
            depth_estimation_type="metric", max_depth=20)
        ip = DPTImageProcessorPil(size={"height": 518, "width": 518}, keep_aspect_ratio=True, ensure_multiple_of=14,
                                  image_mean=[0.485, 0.456, 0.406], image_std=[0.229, 0.224, 0.225], resample=3)
    else:
        cfg = DepthAnythingConfig(
            backbone_config=dict(model_type="dinov2", hidden_size=16, num_hidden_layers=2, num_attention_heads=2,
                                 intermediate_size=32, patch_size=14, image_size=56, out_features=["stage1", "stage2"],
                                 reshape_hidden_states=False),
            reassemble_hidden_size=16, neck_hidden_sizes=[8, 16], fusion_hidden_size=16, head_hidden_size=8,
            depth_estimation_type="metric", max_depth=20)
        ip = DPTImageProcessorPil(size={"height": 56, "width": 56}, keep_aspect_ratio=True, ensure_multiple_of=14)
    path = _save(DepthAnythingForDepthEstimation(cfg).eval(), None, out)
    ip.save_pretrained(path)
    return path


def depth_pro(out: Path, full: bool) -> Path:
    import json

    from transformers import DepthProConfig, DepthProForDepthEstimation

    size = 1536
    if full:
        cfg = DepthProConfig(use_fov_model=True)
    else:
        size = 64
        vit = dict(model_type="dinov2", hidden_size=16, num_hidden_layers=2, num_attention_heads=2,
                   intermediate_size=32, patch_size=4, image_size=16)
        cfg = DepthProConfig(fusion_hidden_size=16, patch_model_config=vit, image_model_config=vit, fov_model_config=vit,
                             intermediate_hook_ids=[1, 0], intermediate_feature_dims=[8, 8], scaled_images_ratios=[0.5, 1.0],
                             scaled_images_overlap_ratios=[0.0, 0.25], scaled_images_feature_dims=[16, 16],
                             merge_padding_value=1, use_fov_model=True, num_fov_head_layers=1, patch_size=16)
    path = _save(DepthProForDepthEstimation(cfg).eval(), None, out)
    (path / "preprocessor_config.json").write_text(json.dumps(
        {"image_processor_type": "DepthProImageProcessor", "size": {"height": size, "width": size},
         "image_mean": [0.5, 0.5, 0.5], "image_std": [0.5, 0.5, 0.5], "rescale_factor": 1 / 255}), "utf-8")
    return path


def zoedepth(out: Path, full: bool) -> Path:
    from transformers import ZoeDepthConfig, ZoeDepthForDepthEstimation, ZoeDepthImageProcessorPil

    if full:
        cfg = ZoeDepthConfig(bin_configurations=[{"n_bins": 64, "min_depth": 0.001, "max_depth": 10.0, "name": "nyu"},
                                                 {"n_bins": 64, "min_depth": 0.001, "max_depth": 80.0, "name": "kitti"}])
        ip = ZoeDepthImageProcessorPil(size={"height": 384, "width": 512}, keep_aspect_ratio=True, ensure_multiple_of=32)
    else:
        cfg = ZoeDepthConfig(
            backbone_config=dict(model_type="beit", hidden_size=16, num_hidden_layers=4, num_attention_heads=2,
                                 intermediate_size=32, image_size=32, patch_size=8, out_indices=[1, 2, 3, 4],
                                 use_relative_position_bias=True, reshape_hidden_states=False),
            neck_hidden_sizes=[8, 8, 16, 16], fusion_hidden_size=16, num_relative_features=8, bin_embedding_dim=16,
            bottleneck_features=16, num_attractors=[4, 2, 2, 1], reassemble_factors=[4, 2, 1, 0.5],
            backbone_hidden_size=16, patch_size=8,
            bin_configurations=[{"n_bins": 8, "min_depth": 0.001, "max_depth": 10.0, "name": "nyu"}])
        ip = ZoeDepthImageProcessorPil(size={"height": 32, "width": 32}, keep_aspect_ratio=True, ensure_multiple_of=8)
    path = _save(ZoeDepthForDepthEstimation(cfg).eval(), None, out)
    ip.save_pretrained(path)
    return path


def clip(out: Path, full: bool) -> Path:
    from transformers import CLIPConfig, CLIPImageProcessorPil, CLIPModel, CLIPProcessor

    tok, n = _clip_tokenizer()
    ids = {"bos_token_id": 1, "eos_token_id": 2, "pad_token_id": 2}
    if full:
        cfg = CLIPConfig(text_config={"vocab_size": max(n, 49408), **ids}, vision_config={"patch_size": 32})
        ip = CLIPImageProcessorPil()
    else:
        cfg = CLIPConfig(text_config=dict(vocab_size=n, hidden_size=16, intermediate_size=32, num_hidden_layers=1,
                                          num_attention_heads=2, max_position_embeddings=32, **ids),
                         vision_config=dict(hidden_size=16, intermediate_size=32, num_hidden_layers=1,
                                            num_attention_heads=2, image_size=32, patch_size=8), projection_dim=16)
        ip = CLIPImageProcessorPil(size={"shortest_edge": 32}, crop_size={"height": 32, "width": 32})
    return _save(CLIPModel(cfg).eval(), CLIPProcessor(image_processor=ip, tokenizer=tok), out)


def siglip(out: Path, full: bool) -> Path:
    from transformers import SiglipConfig, SiglipImageProcessorPil, SiglipModel, SiglipProcessor

    out.mkdir(parents=True, exist_ok=True)
    tok, n = _spm_tokenizer(out)
    if full:
        cfg = SiglipConfig(text_config={"vocab_size": max(n, 32000)})
        ip = SiglipImageProcessorPil()
    else:
        cfg = SiglipConfig(text_config=dict(vocab_size=n, hidden_size=16, intermediate_size=32, num_hidden_layers=1,
                                            num_attention_heads=2, max_position_embeddings=16),
                           vision_config=dict(hidden_size=16, intermediate_size=32, num_hidden_layers=1,
                                              num_attention_heads=2, image_size=32, patch_size=8))
        ip = SiglipImageProcessorPil(size={"height": 32, "width": 32})
    path = _save(SiglipModel(cfg).eval(), SiglipProcessor(image_processor=ip, tokenizer=tok), out)
    for f in ("spm_corpus.txt", "spm.model", "spm.vocab"):
        (path / f).unlink(missing_ok=True)
    return path


def vlm(out: Path, full: bool) -> Path:
    from transformers import BlipConfig, BlipForConditionalGeneration, BlipImageProcessorPil, BlipProcessor

    tok, n = _bert_tokenizer()
    tok.add_special_tokens({"bos_token": "[DEC]"})
    text = dict(vocab_size=n, bos_token_id=tok.convert_tokens_to_ids("[DEC]"), pad_token_id=0, sep_token_id=3)
    if full:
        cfg = BlipConfig(text_config={**text, "vocab_size": max(n, 30524)})
        ip = BlipImageProcessorPil()
    else:
        cfg = BlipConfig(text_config=dict(hidden_size=16, intermediate_size=32, num_hidden_layers=1, num_attention_heads=2,
                                          max_position_embeddings=32, encoder_hidden_size=16, **text),
                         vision_config=dict(hidden_size=16, intermediate_size=32, num_hidden_layers=1,
                                            num_attention_heads=2, image_size=32, patch_size=8), projection_dim=16)
        ip = BlipImageProcessorPil(size={"height": 32, "width": 32})
    return _save(BlipForConditionalGeneration(cfg).eval(), BlipProcessor(image_processor=ip, tokenizer=tok), out)


BUILDERS: dict[str, Callable[[Path, bool], Path]] = {
    "grounding-dino": grounding_dino, "owlv2": owlv2, "sam": sam, "sam2": sam2, "depth-anything": depth_anything,
    "depth-pro": depth_pro, "zoedepth": zoedepth, "clip": clip, "siglip": siglip, "vlm": vlm,
}


def build(family: str, root: str | Path, full: bool = False, seed: int = 0) -> Path:
    """Build one family's random model into `root/<published folder name>` (same seed, same weights)."""
    import torch

    from refspatial_gen.perception.runtime import quiet_transformers

    quiet_transformers()
    torch.manual_seed(seed)
    return BUILDERS[family](Path(root) / FOLDERS[family], full)


def build_all(root: str | Path, families: list[str] | None = None, full: bool = False) -> dict[str, Path]:
    return {f: build(f, root, full) for f in (families or list(BUILDERS))}
