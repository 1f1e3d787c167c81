"""`slides --quick` end to end: every section of the deck's comparisons is on the page with its
images and numbers, the images exist, and the captions show exactly what slides.json holds."""
import html
import json
import re
import shutil

import numpy as np
import pytest

from PIL import Image
from conftest import run_lab
from lab.slides import QUICK_RESOLUTION
from lab.slides.page import caption_text
from lab.slides.sections import SECTIONS

pytestmark = [pytest.mark.blender, pytest.mark.slow]


@pytest.fixture(scope="module")
def slides(tmp_path_factory):
    out = tmp_path_factory.mktemp("slides")
    run_lab("slides", "--out", out, "--quick", timeout=1800)  # every section, the captures' renders too
    return out, json.loads((out / "slides.json").read_text()), (out / "index.html").read_text()


def test_every_section_is_on_the_page_in_the_decks_order(slides):
    _, report, page = slides
    ids = [section["id"] for section in report["sections"]]
    assert len(ids) == len(SECTIONS) == len(set(ids))
    positions = [page.index(f"<section id='{section['id']}'>") for section in report["sections"]]
    assert positions == sorted(positions)
    for section in report["sections"]:
        assert f"<h2>{html.escape(section['title'])}</h2>" in page
        assert section["images"] and section["numbers"]


def test_every_image_the_page_names_exists(slides):
    """Frames and animations at the run's size (every frame of an animation), insets an
    enlarged part of one, charts a readable size."""
    out, report, page = slides
    sources = re.findall(r"<img class='[a-z]+' src='([^']+)'", page)
    images = [image for section in report["sections"] for image in section["images"]]
    assert sorted(sources) == sorted(image["file"] for image in images)
    for image in images:
        with Image.open(out / image["file"]) as opened:
            size, frames = opened.size, getattr(opened, "n_frames", 1)
        if image["kind"] in ("frame", "animation"):
            assert size == QUICK_RESOLUTION, image
        elif image["kind"] == "inset":
            assert size[0] > QUICK_RESOLUTION[0] // 4 and size[1] > QUICK_RESOLUTION[1] // 4, image
        else:
            assert image["kind"] == "chart" and size[0] >= 800, image
        assert (frames > 1) == (image["kind"] == "animation"), image


def test_captions_show_the_numbers_in_slides_json(slides):
    _, report, page = slides
    for section in report["sections"]:
        caption = caption_text(section)
        assert html.escape(caption) in page
        for key, value in section["numbers"].items():
            assert isinstance(value, (int, float)) and np.isfinite(value), (section["id"], key)
            assert str(value) in caption, (section["id"], key)


def test_ssr_beats_no_ssr_and_the_cubemap_on_the_mirror_floor(slides):
    """What the first slides say, measured: against Cycles, SSR is closer than the world alone
    and than one cubemap on the mirror floor's reflective pixels."""
    numbers = {section["id"]: section["numbers"] for section in slides[1]["sections"]}
    assert numbers["ssr_on_off"]["on_flip"] < numbers["ssr_on_off"]["off_flip"]
    assert numbers["cubemaps"]["ssr_flip"] < numbers["cubemaps"]["cubemap_flip"]


def test_each_slide_shows_what_its_caption_says(slides):
    """The deck's claims, measured on the slides' own renders: each section's caption says
    which way the comparison goes, so a chain that broke a stage would contradict its slide."""
    numbers = {section["id"]: section["numbers"] for section in slides[1]["sections"]}
    sampling = numbers["importance_sampling"]
    assert sampling["halton_noise"] < sampling["uniform_noise"]
    assert sampling["halton_noise16"] < sampling["uniform_noise16"]
    assert sampling["halton_noise16"] < sampling["random_noise16"]  # strata filled evenly
    assert numbers["neighbour_reuse"]["reuse4_noise"] < numbers["neighbour_reuse"]["reuse1_noise"]
    temporal = numbers["temporal_filter"]
    assert temporal["on_flicker"] < temporal["off_flicker"] and temporal["on_noise"] < temporal["off_noise"]
    assert numbers["reprojection"]["hit_flip"] < numbers["reprojection"]["surface_flip"]
    cones = numbers["filtered_importance_sampling"]
    assert cones["cone_noise"] < cones["monte_carlo_noise"]
    walk = numbers["hierarchical_ray_trace"]
    assert walk["visits"] < walk["pixel_tests"] and walk["highest_level"] >= 2
    rays = numbers["cheap_and_expensive_rays"]
    assert rays["deck_expensive_share"] <= 0.21
    assert rays["balanced_expensive_share"] >= rays["budget"]
    sparse = numbers["sparse_ray_tracing"]
    # A quarter of the rays (the work, not its time: timings belong in the benchmarks).
    assert sparse["half_rays"] < 0.3 * sparse["full_rays"] and sparse["half_gap"] < sparse["half_resolve_gap"]
    assert numbers["limits"]["hidden_flip"] < numbers["limits"]["hidden_fallback_flip"]


def test_some_sections_rerun_replace_their_own_and_keep_the_others(slides, tmp_path):
    """--sections into a folder with a run at the same size: the page keeps every section, the
    ones run now rewritten, the rest as they were."""
    out, report, _ = slides
    shutil.copytree(out, tmp_path, dirs_exist_ok=True)
    earlier = json.loads(json.dumps(report))
    titles = {section["id"]: section["title"] for section in report["sections"]}
    for section in earlier["sections"]:
        section["title"] = "kept from the earlier run"
    (tmp_path / "slides.json").write_text(json.dumps(earlier))
    run_lab("slides", "--out", tmp_path, "--quick", "--sections", "basic_algorithm")
    merged = json.loads((tmp_path / "slides.json").read_text())
    assert [section["id"] for section in merged["sections"]] == [section["id"] for section in report["sections"]]
    for section in merged["sections"]:
        rerun = section["id"] == "basic_algorithm"
        assert section["title"] == (titles[section["id"]] if rerun else "kept from the earlier run")
    assert (tmp_path / "index.html").read_text().count("<section id=") == len(SECTIONS)


@pytest.mark.parametrize("arguments, named", [(("--resolution", "64by36"), "64by36"),
                                              (("--sections", "temporal_filter", "hizz"), "hizz")])
def test_bad_slides_input_gets_one_clear_line(tmp_path, arguments, named):
    result = run_lab("slides", "--out", tmp_path / "out", *arguments, check=False)
    lines = [line for line in result.stderr.splitlines() if line.strip() and "EGL" not in line]
    assert result.returncode == 2
    assert len(lines) == 1 and lines[0].startswith("error:") and named in lines[0], result.stderr
    assert not (tmp_path / "out").exists()
