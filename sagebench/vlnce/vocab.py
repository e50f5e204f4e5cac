"""Instruction tokens the way habitat's VLN datasets hold them: word ids into a vocabulary, padded.

Two tokenizers (`tokenize`):
- `sagebench`: the lower-cased words (runs of word characters and "-"), with a possessive "'s" as a token of its
  own; punctuation is dropped.
- `habitat`: habitat-lab's `tokenize` (habitat/datasets/utils.py) with its defaults as written up to 0.1.5, when
  R2R-CE was published (keep=["'s"], remove=[",", "?"]): lower case, "'s" spaced off, "," and "?" removed, then
  split at runs of anything but word characters and "-", each run kept as a token of its own when it is not blank
  ("." and "'" are tokens; "'s" becomes "'" and "s"). From 0.1.6 on the default reads keep=("'s"), a string,
  which spaces off every "'" and every "s" instead (stairs -> stair, s): not what this tokenizer does.
The run's vocabulary starts with habitat's special tokens (VocabDict's <pad>, <unk>, <s>, </s>) so <pad> is 0 and
<unk> is 1, as in R2R-CE. `read_vocabulary` reads a given one in VLN-CE's format.
"""

from __future__ import annotations

import functools
import gzip
import re
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path

from sagebench.errors import DataError
from sagebench.input_files import loads_json, read_input

SPECIAL_TOKENS = ("<pad>", "<unk>", "<s>", "</s>")
PAD_TOKEN, UNK_TOKEN = SPECIAL_TOKENS[:2]
PAD_INDEX, UNK_INDEX = 0, 1
TOKENS_PER_INSTRUCTION = 200  # R2R-CE pads (and cuts) every instruction to this many ids
TOKENIZERS = ("sagebench", "habitat")
_TOKEN = re.compile(r"'s\b|[\w-]+")
_HABITAT_SPLIT = re.compile(r"([^\w-]+)")  # habitat's SENTENCE_SPLIT_REGEX


def tokenize(text: str, tokenizer: str = "sagebench") -> list[str]:
    """The tokens of `text` by one of TOKENIZERS (module docstring)."""
    if tokenizer == "habitat":
        text = text.lower().replace("'s", " 's").replace(",", "").replace("?", "")
        return [t.strip() for t in _HABITAT_SPLIT.split(text) if t.strip()]
    return _TOKEN.findall(text.lower())


@dataclass(frozen=True)
class Vocabulary:
    word_list: tuple[str, ...]  # index -> word; the run's: SPECIAL_TOKENS first
    tokenizer: str = "sagebench"

    @classmethod
    def from_texts(cls, texts: Iterable[str], tokenizer: str = "sagebench") -> Vocabulary:
        """The special tokens, then every token of `texts` once, sorted (so the order never depends on rows)."""
        words = {t for text in texts for t in tokenize(text, tokenizer)} - set(SPECIAL_TOKENS)
        return cls((*SPECIAL_TOKENS, *sorted(words)), tokenizer)

    @functools.cached_property
    def index(self) -> dict[str, int]:
        return {w: i for i, w in enumerate(self.word_list)}

    def encode(self, text: str, length: int = TOKENS_PER_INSTRUCTION) -> list[int]:
        """Word ids of `text`, unknown words as <unk>'s id, cut or padded with <pad>'s to `length`."""
        unk, pad = self.index[UNK_TOKEN], self.index[PAD_TOKEN]
        ids = [self.index.get(t, unk) for t in tokenize(text, self.tokenizer)][:length]
        return ids + [pad] * (length - len(ids))

    def unknown(self, text: str) -> tuple[int, int]:
        """(tokens of `text` not in the vocabulary, tokens) over the whole text, before any cut."""
        tokens = tokenize(text, self.tokenizer)
        return sum(t not in self.index for t in tokens), len(tokens)

    def coverage(self, source: Path, texts: list[str]) -> str:
        """What a vocabulary given (read from `source`) lacks of `texts`, one an episode: `vocabulary FILE: N words,
        the T tokenizer; K of the M instruction tokens of the E episodes are not in it (<unk>)`."""
        counts = [self.unknown(text) for text in texts]
        unknown, total = sum(u for u, _ in counts), sum(t for _, t in counts)
        return (f"vocabulary {source}: {len(self.word_list):,} words, the {self.tokenizer} tokenizer; {unknown:,} of "
                f"the {total:,} instruction tokens of the {len(texts):,} episodes are not in it (<unk>)")

    def to_json(self) -> dict:
        """The dataset file's instruction_vocab (habitat's VocabDict reads word_list)."""
        return {"word_list": list(self.word_list), "num_vocab": len(self.word_list),
                "PAD_INDEX": self.index[PAD_TOKEN], "UNK_INDEX": self.index[UNK_TOKEN]}

    def to_text(self) -> str:
        """One word a line: the file VocabDict(filepath=...) reads."""
        return "".join(f"{w}\n" for w in self.word_list)


def read_vocabulary(path: Path, tokenizer: str) -> Vocabulary:
    """The vocabulary in `path`, VLN-CE's format: a JSON file (gzipped or not) holding an R2R-CE dataset's
    `instruction_vocab` (or being one): `word_list` or `itos` (index -> word), with `word2idx_dict`, `stoi` or
    `word2idx` (word -> index) checked against it when given. As habitat's VocabDict does, <unk> goes first when
    the list lacks it. A DataError names what is wrong."""
    data = read_input(path)
    if data[:2] == b"\x1f\x8b":
        try:
            data = gzip.decompress(data)
        except (OSError, EOFError) as err:
            raise DataError(f"not a readable gzip file: {err}", path=path) from None
    doc = loads_json(data, path)
    vocab = doc.get("instruction_vocab", doc) if isinstance(doc, dict) else None
    words = next((vocab[k] for k in ("word_list", "itos") if k in vocab), None) if isinstance(vocab, dict) else None
    if not isinstance(words, list) or not all(isinstance(w, str) for w in words) or not words:
        raise DataError("expected VLN-CE's instruction_vocab: a JSON object with word_list (or itos), a list of "
                        "words", path=path)
    index = next((vocab[k] for k in ("word2idx_dict", "stoi", "word2idx") if k in vocab), None)
    if index is not None:
        wrong = [w for w, i in index.items() if not isinstance(i, int) or not 0 <= i < len(words) or words[i] != w] \
            if isinstance(index, dict) else ["(not an object)"]
        if wrong or len(index) != len(words):
            raise DataError(f"its word -> index map disagrees with word_list (at {wrong[0] if wrong else 'its size'})",
                            path=path)
    if len(set(words)) != len(words):
        raise DataError("word_list holds a word twice", path=path)
    if PAD_TOKEN not in words:
        raise DataError(f"word_list has no {PAD_TOKEN} (VLN-CE pads instruction_tokens with its id)", path=path)
    return Vocabulary(tuple(words if UNK_TOKEN in words else [UNK_TOKEN, *words]), tokenizer)
