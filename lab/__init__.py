"""The lab: everything that measures the add-on rather than ships in it. `python -m lab COMMAND`
runs the bench, the slides, the error budget and the benchmarks (lab/__main__.py lists them).
It needs the dev packages (flip-evaluator, scikit-image, matplotlib) and the repository's
test_scenes/; the extension zip holds none of it."""
