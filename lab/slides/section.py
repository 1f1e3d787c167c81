"""What every slide section is made of, and the settings the sections share."""

# One frame's worth of rays, nothing accumulated: one iteration (one ray per 2x2 pixels at half
# resolution), no spatial filter, so what a sampling choice does to the noise shows unhidden.
ONE_ITERATION = dict(accumulate_iterations=1, noise_threshold=0.0, use_spatial_filter=False)
# The same chain run until it has settled: the image the noise is measured against.
CONVERGED = dict(accumulate_iterations=64, noise_threshold=0.0)


def section(title, images, numbers, caption):
    """A section of the page (its id is its builder's name): the deck's TITLE, IMAGES side by side ((label, file) or
    (label, file, kind) with kind "frame" (default), "inset", "animation" or "chart"), the
    NUMBERS measured and a CAPTION whose {fields} are those numbers (page.py fills them in, so
    the page shows exactly what slides.json holds)."""
    return {"title": title,
            "images": [{"label": image[0], "file": image[1], "kind": image[2] if len(image) > 2 else "frame"}
                       for image in images],
            "numbers": numbers, "caption": caption}
