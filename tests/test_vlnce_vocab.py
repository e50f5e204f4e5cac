"""A pretrained VLN-CE checkpoint's vocabulary (--vocab, VLN-CE's format) and habitat's tokenizer: the ids an agent
gets are those habitat's tokenize and that vocabulary give, unknown words <unk> and counted."""

from __future__ import annotations

import gzip
import json
import re

import pytest

from sagebench.navsim.simulator import Simulator
from sagebench.settings.rollout import EnvConfig

SPLIT = re.compile(r"([^\w-]+)")  # habitat-lab's SENTENCE_SPLIT_REGEX


def habitat_tokens(sentence: str) -> list[str]:
    """habitat-lab's tokenize (datasets/utils.py) with its defaults keep=["'s"], remove=[",", "?"], written here."""
    sentence = sentence.lower()
    for token in ["'s"]:
        sentence = sentence.replace(token, " " + token)
    for token in [",", "?"]:
        sentence = sentence.replace(token, "")
    return [t.strip() for t in SPLIT.split(sentence) if len(t.strip()) > 0]


def r2r_vocab_file(path, words: list[str]) -> dict[str, int]:
    """An R2R-CE dataset file (gzipped JSON) whose instruction_vocab is VocabDict's, as habitat serialises it:
    <pad>, <unk>, <s>, </s>, then `words`; returns word -> id."""
    word_list = ["<pad>", "<unk>", "<s>", "</s>", *words]
    index = {w: i for i, w in enumerate(word_list)}
    vocab = {"word_list": word_list, "word2idx_dict": index, "stoi": index, "itos": word_list,
             "num_vocab": len(word_list), "UNK_INDEX": 1, "PAD_INDEX": 0}
    path.write_bytes(gzip.compress(json.dumps({"episodes": [], "instruction_vocab": vocab}).encode()))
    return index


def expected_ids(text: str, index: dict[str, int]) -> list[int]:
    ids = [index.get(t, index["<unk>"]) for t in habitat_tokens(text)][:200]
    return ids + [index["<pad>"]] * (200 - len(ids))


def some_words(texts) -> list[str]:
    """Every other word (sorted) of `texts` by habitat's tokenizer: the rest are unknown."""
    return sorted({t for text in texts for t in habitat_tokens(text)})[::2]


def test_every_demo_instruction_gets_habitats_tokens_in_the_given_vocabulary(demo_eval_run, tmp_path):
    texts = Simulator(demo_eval_run, EnvConfig(profile="vlnce")).instructions
    index = r2r_vocab_file(tmp_path / "train.json.gz", some_words(texts.values()))
    assert any(re.search(r"[.,'!]", t) for t in texts.values())  # punctuation for the tokenizers to differ on
    sim = Simulator(demo_eval_run, EnvConfig(profile="vlnce", tokenizer="habitat", vocab=tmp_path / "train.json.gz"))
    results = sim.start(sim.order)
    for eid, r in zip(sim.order, results):
        assert r.observation["instruction_tokens"].tolist() == expected_ids(texts[eid], index), texts[eid]
    assert len(results) == len(texts) > 8


class _Reader:
    """Stops at once, keeping the instruction it was given."""

    seen: list[dict] = []

    def reset(self):
        pass

    def act(self, observations):
        _Reader.seen.append(observations["instruction"])
        return {"action": 0}


def test_the_agent_gets_the_given_vocabularys_ids_and_unknown_words_are_counted(tiny_run, tmp_path, run_cli,
                                                                                  monkeypatch):
    import vlnce_agents

    monkeypatch.setattr(vlnce_agents, "Reader", _Reader, raising=False)
    _Reader.seen = []
    texts = Simulator(tiny_run, EnvConfig(profile="vlnce")).instructions
    index = r2r_vocab_file(tmp_path / "vocab.json.gz", some_words(texts.values()))
    code, stdout, err = run_cli("rollout", "--run", tiny_run, "--out", tmp_path / "p.jsonl", "--policy",
                                "vlnce:vlnce_agents:Reader", "--preset", "vlnce", "--vocab", tmp_path / "vocab.json.gz",
                                "--episodes", "3", "--seed", "1")
    assert code == 0, err
    seen = [i["text"] for i in _Reader.seen]
    tokens = [t for text in seen for t in habitat_tokens(text)]
    unknown = sum(t not in index for t in tokens)
    assert 0 < unknown < len(tokens) and len(seen) == 3
    assert (f"vocabulary {tmp_path / 'vocab.json.gz'}: {len(index)} words, the habitat tokenizer; {unknown} of the "
            f"{len(tokens)} instruction tokens of the 3 episodes are not in it (<unk>)\n") in stdout
    assert [i["tokens"] for i in _Reader.seen] == [expected_ids(text, index) for text in seen]


@pytest.mark.parametrize("content, args, message", [
    (b'{"instruction_vocab": {"words": []}}', ("--preset", "vlnce"),
     "{vocab}: expected VLN-CE's instruction_vocab: a JSON object with word_list (or itos), a list of words"),
    (b'{"word_list": ["<pad>", "a"], "word2idx_dict": {"<pad>": 0, "a": 0}}', ("--preset", "vlnce"),
     "{vocab}: its word -> index map disagrees with word_list (at a)"),
    (b'{"itos": ["<unk>", "a"]}', ("--preset", "vlnce"),
     "{vocab}: word_list has no <pad> (VLN-CE pads instruction_tokens with its id)"),
    (b'{"itos": ["<pad>", "a"]}', ("--policy", "straight"),
     "--vocab: the custom profile has no instruction_tokens (vlnce and full have)"),
])
def test_a_bad_vocabulary_is_one_line_and_nothing_is_written(tiny_run, tmp_path, run_cli, content, args, message):
    from test_fuzz_inputs import snapshot

    vocab = tmp_path / "vocab.json"
    vocab.write_bytes(content)
    before = snapshot(tiny_run)
    code, stdout, err = run_cli("rollout", "--run", tiny_run, "--out", tmp_path / "p.jsonl", "--vocab", vocab, *args)
    assert (code, stdout, err) == (2, "", f"error: {message.format(vocab=vocab)}\n")
    assert [p.name for p in tmp_path.iterdir()] == ["vocab.json"] and snapshot(tiny_run) == before


def _exported(out, split: str = "train") -> dict:
    return json.loads(gzip.decompress((out / split / f"{split}.json.gz").read_bytes()))


def test_export_vlnce_tokenizes_with_the_given_vocabulary(tiny_run, tmp_path, run_cli):
    """export-vlnce --vocab R2R's --tokenizer habitat: each exported instruction's tokens are the ids habitat's
    tokenize and that vocabulary give (what a pretrained VLN-CE model embeds), the files hold that vocabulary, and
    the summary counts the words it lacks."""
    texts = Simulator(tiny_run, EnvConfig(profile="vlnce")).instructions
    index = r2r_vocab_file(tmp_path / "train.json.gz", some_words(texts.values()))
    code, stdout, err = run_cli("export-vlnce", tiny_run, "--out", tmp_path / "out", "--tokenizer", "habitat",
                                "--vocab", tmp_path / "train.json.gz")
    assert code == 0, err
    data = _exported(tmp_path / "out")
    episodes = [e["instruction"] for e in data["episodes"]]
    assert len(episodes) == len(texts) >= 4
    assert [e["instruction_tokens"] for e in episodes] == [expected_ids(e["instruction_text"], index) for e in episodes]
    assert data["instruction_vocab"]["word_list"] == list(index) == (tmp_path / "out" / "vocab.txt").read_text().split()
    tokens = [t for e in episodes for t in habitat_tokens(e["instruction_text"])]
    unknown = sum(t not in index for t in tokens)
    assert 0 < unknown < len(tokens)
    assert (f"vocabulary {tmp_path / 'train.json.gz'}: {len(index)} words, the habitat tokenizer; {unknown} of the "
            f"{len(tokens)} instruction tokens of the {len(episodes)} episodes are not in it (<unk>)\n") in stdout


def test_export_vlnce_with_habitats_tokenizer_gives_the_closed_loops_ids(tiny_run, tmp_path, run_cli):
    """--tokenizer habitat without a vocabulary: the dataset's tokens are the ids rollout's agent gets under the same
    option, so a model trained on the export reads the closed loop's instructions alike."""
    assert run_cli("export-vlnce", tiny_run, "--out", tmp_path / "out", "--tokenizer", "habitat")[0] == 0
    sim = Simulator(tiny_run, EnvConfig(profile="vlnce", tokenizer="habitat"))
    exported = {e["episode_id"]: e["instruction"]["instruction_tokens"] for e in _exported(tmp_path / "out")["episodes"]}
    given = {eid: r.observation["instruction_tokens"].tolist() for eid, r in zip(sim.order, sim.start(sim.order))}
    assert exported == given and len(given) >= 4
    assert _exported(tmp_path / "out")["instruction_vocab"]["word_list"] == list(sim.vocabulary.word_list)
