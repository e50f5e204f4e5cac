"""The VLN-CE config options a user adds to train or evaluate on an exported dataset, as `KEY VALUE` pairs.

VLN-CE's run.py takes them after its arguments (`python run.py --exp-config CFG --run-type train KEY VALUE ...`,
merged last by yacs): where the data and the ground truth are, the vocabulary's size (its default configs say
R2R's 2504, and load GloVe embeddings indexed by R2R's words, which do not fit another vocabulary), the success
distance the episodes were made for, nDTW's threshold, and splits the dataset has (VLN-CE's CMA config
evaluates on val_unseen, which a run of seen scenes only does not hold).
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

DATA = "{split}/{split}.json.gz"  # VLN-CE formats {split} itself
GT = "{split}/{split}_gt.json.gz"
EVAL_ORDER = ("val_unseen", "val_seen", "test", "train")  # the eval split VLN-CE's configs prefer, first present


def vlnce_opts(out_dir: Path, scenes_dir: str, splits: Sequence[str], vocab_size: int, success_distance: float,
               ndtw_distance: float) -> list[tuple[str, str]]:
    """(key, value) pairs, in this order: data, scenes, train and eval splits, success distances, nDTW, the
    recollect trainer's gt file, the instruction encoder's vocabulary."""
    root = Path(out_dir).resolve()
    train = "train" if "train" in splits else splits[0]
    evaluate = next(s for s in EVAL_ORDER if s in splits)
    d = f"{success_distance:g}"
    return [
        ("TASK_CONFIG.DATASET.DATA_PATH", str(root / DATA)),
        ("TASK_CONFIG.DATASET.SCENES_DIR", str(root / scenes_dir)),
        ("TASK_CONFIG.DATASET.SPLIT", train),
        ("EVAL.SPLIT", evaluate),
        ("TASK_CONFIG.TASK.SUCCESS.SUCCESS_DISTANCE", d),
        ("TASK_CONFIG.TASK.SPL.SUCCESS_DISTANCE", d),
        ("TASK_CONFIG.TASK.ORACLE_SUCCESS.SUCCESS_DISTANCE", d),
        ("TASK_CONFIG.TASK.NDTW.SUCCESS_DISTANCE", f"{ndtw_distance:g}"),
        ("TASK_CONFIG.TASK.NDTW.GT_PATH", str(root / GT)),
        ("IL.RECOLLECT_TRAINER.gt_file", str(root / GT)),
        ("MODEL.INSTRUCTION_ENCODER.vocab_size", str(vocab_size)),
        ("MODEL.INSTRUCTION_ENCODER.use_pretrained_embeddings", "False"),
        ("MODEL.INSTRUCTION_ENCODER.dataset_vocab", str(root / DATA.format(split=train))),
    ]


def opts_text(opts: Sequence[tuple[str, str]]) -> str:
    """One `KEY VALUE` a line: `$(cat FILE)` after run.py's arguments."""
    return "".join(f"{k} {v}\n" for k, v in opts)
