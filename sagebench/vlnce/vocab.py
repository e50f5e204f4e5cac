"""Instruction tokens the way habitat's VLN datasets hold them: word ids into a vocabulary, padded.

Tokens: the lower-cased words (runs of word characters and "-"), with a possessive "'s" as a token of
its own; punctuation is dropped. The vocabulary starts with habitat's special tokens (VocabDict's
<pad>, <unk>, <s>, </s>) so <pad> is 0 and <unk> is 1, as in R2R-CE.
"""

from __future__ import annotations

import re
from collections.abc import Iterable
from dataclasses import dataclass

SPECIAL_TOKENS = ("<pad>", "<unk>", "<s>", "</s>")
PAD_INDEX, UNK_INDEX = 0, 1
TOKENS_PER_INSTRUCTION = 200  # R2R-CE pads (and cuts) every instruction to this many ids
_TOKEN = re.compile(r"'s\b|[\w-]+")


def tokenize(text: str) -> list[str]:
    return _TOKEN.findall(text.lower())


@dataclass(frozen=True)
class Vocabulary:
    word_list: tuple[str, ...]  # index -> word; SPECIAL_TOKENS first

    @classmethod
    def from_texts(cls, texts: Iterable[str]) -> Vocabulary:
        """The special tokens, then every token of `texts` once, sorted (so the order never depends on rows)."""
        words = {t for text in texts for t in tokenize(text)} - set(SPECIAL_TOKENS)
        return cls((*SPECIAL_TOKENS, *sorted(words)))

    def encode(self, text: str, length: int = TOKENS_PER_INSTRUCTION) -> list[int]:
        """Word ids of `text`, unknown words as UNK_INDEX, cut or padded with PAD_INDEX to `length`."""
        index = {w: i for i, w in enumerate(self.word_list)}
        ids = [index.get(t, UNK_INDEX) for t in tokenize(text)][:length]
        return ids + [PAD_INDEX] * (length - len(ids))

    def to_json(self) -> dict:
        """The dataset file's instruction_vocab (habitat's VocabDict reads word_list)."""
        return {"word_list": list(self.word_list), "num_vocab": len(self.word_list),
                "PAD_INDEX": PAD_INDEX, "UNK_INDEX": UNK_INDEX}

    def to_text(self) -> str:
        """One word a line: the file VocabDict(filepath=...) reads."""
        return "".join(f"{w}\n" for w in self.word_list)
