"""The bench end to end on one tiny scene: every output present and consistent, the reference cached."""
import csv
import json

import pytest

from PIL import Image

from conftest import SCENES, run_cli, run_lab
from lab import bench

pytestmark = [pytest.mark.blender, pytest.mark.slow]

SCENE = "glossy_corridor"  # no lamps, so no lamp split
TINY = ("--scenes", SCENE, "--resolution", "64x36", "--frames", "1", "--samples", "1", "--reference-samples", "64",
        "--no-stability")


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    """A full run, then a second one of one contender sharing the reference cache."""
    root = tmp_path_factory.mktemp("bench")
    cache = root / "cache"
    run_lab("bench", *TINY, "--cache", cache, "--out", root / "first")
    run_lab("bench", *TINY, "--cache", cache, "--out", root / "second", "--contenders", "none")
    return {name: json.loads((root / name / "bench.json").read_text()) for name in ("first", "second")}, root


def test_every_output_is_written(runs):
    _, root = runs
    for name in ("bench.json", "bench.csv", "speed_vs_accuracy.png", "contact_sheet.png"):
        assert (root / "first" / name).stat().st_size > 0, name
    for name in ("speed_vs_accuracy.png", "contact_sheet.png"):
        assert (root / "first" / name).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert not list((root / "first").glob(".*.partial"))


def test_every_contender_is_scored_against_the_reference(runs):
    report = runs[0]["first"]
    names = [contender.name for contender in bench.all_contenders()]
    assert [entry["name"] for entry in report["contenders"]] == names
    assert [row["contender"] for row in report["results"]] == names
    for row in report["results"]:
        for region in ("reflective", "all"):
            assert 0.0 <= row[f"flip_{region}"] <= 1.0, row
            assert -1.0 <= row[f"ssim_{region}"] <= 1.0, row
            assert row[f"psnr_{region}"] > 0.0, row
        assert row["frame_ms"] > 0 and row["frame_x_copy"] == pytest.approx(
            row["frame_ms"] / report["copy_pass_ms"]["64x36"])
    ours = [row for row in report["results"] if row["method"] == "ssr"]
    assert ours and all(set(row["stages_ms"]) > {"render"} for row in ours), "our stages are timed one by one"
    assert set(report["copy_pass_ms"]) == {"64x36", "1600x900"}
    assert all(ms > 0 for ms in report["copy_pass_ms"].values())


def test_pareto_front_is_the_undominated_contenders(runs):
    contenders = runs[0]["first"]["contenders"]
    front = [entry for entry in contenders if entry["pareto"]]
    assert front
    for entry in contenders:
        point = (entry["frame_ms"], entry["flip_reflective"])
        dominated = any(other["frame_ms"] <= point[0] and other["flip_reflective"] <= point[1]
                        and (other["frame_ms"], other["flip_reflective"]) != point for other in contenders)
        assert entry["pareto"] == (not dominated), entry["name"]


def test_csv_matches_json(runs):
    report, root = runs[0]["first"], runs[1]
    with open(root / "first" / "bench.csv", newline="") as stream:
        rows = list(csv.DictReader(stream))
    assert len(rows) == 2 * len(report["contenders"])  # per scene (one here), then the means
    for row, result in zip(rows, report["results"]):
        assert (row["scene"], row["contender"]) == (result["scene"], result["contender"])
        assert float(row["flip_reflective"]) == pytest.approx(result["flip_reflective"], rel=1e-5)


def test_reference_is_rendered_once(runs):
    first, second = (runs[0][name]["reference"]["per_scene"][SCENE] for name in ("first", "second"))
    assert first["cached"] is False and second["cached"] is True
    assert second["noise_rmse"] == first["noise_rmse"]
    assert 0.0 <= first["noise_flip_reflective"] <= 1.0
    assert [entry["name"] for entry in runs[0]["second"]["contenders"]] == ["none"]
    none_first = next(row for row in runs[0]["first"]["results"] if row["contender"] == "none")
    none_second = runs[0]["second"]["results"][0]
    assert none_second["flip_reflective"] == pytest.approx(none_first["flip_reflective"], abs=1e-6)


def test_page_block_is_replaced_in_place(runs, tmp_path):
    report, root = runs[0]["first"], runs[1]
    page = tmp_path / "measurements.md"
    page.write_text("# Project\n\nIntro.\n")
    for _ in range(2):
        bench.update_page(str(page), report, str(root / "first"))
    text = page.read_text()
    assert text.startswith("# Project\n\nIntro.\n\n## Benchmark\n")
    assert text.count("## Benchmark") == 1
    assert text.count("<!-- bench:start -->") == 1 and text.count("<!-- bench:end -->") == 1
    for entry in report["contenders"]:
        assert f"| {entry['name']} |" in text
    assert "speed_vs_accuracy.png" in text


@pytest.mark.parametrize("extra, expected", [
    (("--scenes", "no_such_scene"), "no_such_scene"),
    (("--contenders", "nothing*"), "--contenders"),
    (("--contenders", "none", "ssr balanced lamp_split=nothing"), "lamp_split=nothing"),  # not dropped silently
    (("--resolution", "64by36"), "--resolution"),
    (("--frames", "0"), "--frames"),
])
def test_bad_bench_input_gets_one_clear_line(tmp_path, extra, expected):
    result = run_lab("bench", "--out", tmp_path / "out", "--no-stability", *extra, check=False)
    lines = [line for line in result.stderr.splitlines() if line.strip() and "EGL" not in line]
    assert result.returncode == 2
    assert len(lines) == 1 and lines[0].startswith("error:") and expected in lines[0], result.stderr
    assert not (tmp_path / "out").exists()


def test_the_demo_ends_with_ssr_off_and_on_side_by_side(runs, tmp_path):
    """`make demo`'s last step: the two renders side by side, each labelled with its error against
    Cycles where the bench has the reference cached (here the bench run's), and the path printed."""
    _, root = runs
    scene = f"{SCENES}/{SCENE}.py"
    for method in ("none", "ssr"):
        run_cli("render", scene, "--method", method, "--resolution", "64x36", "--samples", "1",
                "--out", tmp_path / method)
    result = run_lab("demo", scene, tmp_path, "--cache", root / "cache", "--reference-samples", "64")
    path = tmp_path / "side_by_side.png"
    assert str(path) in result.stdout and "no Cycles reference" not in result.stdout
    with Image.open(path) as sheet:
        assert sheet.size[0] == 2 * 64 and sheet.size[1] > 36  # two tiles under their labels
