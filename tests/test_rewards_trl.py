"""The TRL adapters inside a real `trl.GRPOTrainer` (tiny random model built from a config, CPU, no downloads)."""

import json

import numpy as np
import pytest

pytest.importorskip("trl", reason="trl is in the 'rl' extra (make setup-test installs it)")
pytestmark = pytest.mark.slow


def _tokenizer():
    from tokenizers import Tokenizer, models, pre_tokenizers, trainers
    from transformers import PreTrainedTokenizerFast

    tok = Tokenizer(models.WordLevel(unk_token="[UNK]"))
    tok.pre_tokenizer = pre_tokenizers.Whitespace()
    corpus = ["<think> </think> <answer> </answer> [Position] [the cup]: (0.485, 0.439) Point to the cup"] * 4
    tok.train_from_iterator(corpus, trainers.WordLevelTrainer(special_tokens=["[UNK]", "[PAD]", "[EOS]"]))
    return PreTrainedTokenizerFast(tokenizer_object=tok, unk_token="[UNK]", pad_token="[PAD]", eos_token="[EOS]")


def _gold() -> str:
    from refspatial_gen.core.mask import RLE
    from refspatial_gen.rewards.gold import Gold

    m = np.zeros((480, 640), bool)
    m[200:220, 300:320] = True
    return Gold("q", "points", (640, 480), "[(0.485, 0.439)]", True,
                [{"type": "Position", "phrase": "the cup", "value": [0.485, 0.439]}],
                points=[[0.485, 0.439]], mask=RLE.encode(m).to_json()).dumps()


def test_grpo_trainer_calls_the_reward_functions(tmp_path):
    from datasets import Dataset
    from transformers import Qwen2Config, Qwen2ForCausalLM
    from trl import GRPOConfig, GRPOTrainer

    from refspatial_gen.rewards.adapters import trl_reward_funcs, trl_reward_weights

    tok = _tokenizer()
    cfg = Qwen2Config(vocab_size=len(tok), hidden_size=16, intermediate_size=32, num_hidden_layers=1,
                      num_attention_heads=2, num_key_value_heads=1, max_position_embeddings=64,
                      pad_token_id=tok.pad_token_id, eos_token_id=tok.eos_token_id)
    model = Qwen2ForCausalLM(cfg)
    gt = _gold()
    ds = Dataset.from_list([{"prompt": "Point to the cup", "reward_model": {"style": "rule", "ground_truth": gt}}] * 4)
    args = GRPOConfig(output_dir=str(tmp_path), per_device_train_batch_size=2, num_generations=2, max_completion_length=6,
                      max_steps=1, report_to=[], use_cpu=True, bf16=False, logging_steps=1, save_strategy="no",
                      reward_weights=trl_reward_weights())
    trainer = GRPOTrainer(model=model, reward_funcs=trl_reward_funcs(), args=args, train_dataset=ds, processing_class=tok)
    trainer.train()  # random completions: the rewards are computed and logged under each function's name
    logged = {k for h in trainer.state.log_history for k in h}
    assert {"rewards/format_reward/mean", "rewards/point_reward/mean", "rewards/process_accuracy_reward/mean"} <= logged
    # the trainer's own reward path on chosen completions: gold scores 1 everywhere, garbage 0
    gold = "<think>[Position] [the cup]: (0.485, 0.439)</think><answer>[(0.485, 0.439)]</answer>"
    inputs = [{"prompt": "Point to the cup", "reward_model": {"style": "rule", "ground_truth": gt}}] * 2
    r = trainer._calculate_rewards(inputs, ["Point to the cup"] * 2, [gold, "(0.9"], [[1], [2]])
    assert r.tolist() == [[1.0, 1.0, 1.0, 1.0], [0.0, 0.0, 0.0, 0.0]]
    json.dumps(trainer.state.log_history)
