"""The generated blocks of the measurements page (docs/measurements.md): each lab command that
measures rewrites its own block, between <!-- NAME:start --> and <!-- NAME:end -->."""
import os

from ssr_addon.batch.cli import ArgumentParser
from ssr_addon.batch.outputs import written_together
from ssr_addon.batch.request import parse_resolution
from ssr_addon.core.errors import SSRError

MEASUREMENTS = os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "docs", "measurements.md")


def require_page(path):
    """Refuse, in one line, a page to rewrite that does not exist."""
    if path and not os.path.isfile(path):
        raise SSRError(f"--page {path}: no such file")


def rewrite_block(page, name, body, heading):
    """Replace PAGE's generated block NAME with BODY, or append it under HEADING if absent;
    the file is replaced whole or not at all."""
    start, end = f"<!-- {name}:start -->", f"<!-- {name}:end -->"
    with open(page, encoding="utf-8") as stream:
        text = stream.read()
    block = f"{start}\n{body}\n{end}"
    if start in text and end in text:
        head, _, rest = text.partition(start)
        _, _, tail = rest.partition(end)
        text = head + block + tail
    else:
        text = text.rstrip("\n") + f"\n\n## {heading}\n\n{block}\n"
    with written_together([page]) as (partial,), open(partial, "w", encoding="utf-8") as stream:
        stream.write(text)


def page_link(page, path):
    """PATH (from the repository root) as the markdown page PAGE links to it."""
    return os.path.relpath(os.path.abspath(path), os.path.dirname(os.path.abspath(page)))


def format_resolutions(resolutions):
    """RESOLUTIONS ((width, height) pairs) as a command line names them: "160x90 1280x720"."""
    return " ".join("{}x{}".format(*resolution) for resolution in resolutions)


def scenes_parser(command, doc, scenes, resolution, block):
    """The argument parser of a lab COMMAND that measures SCENES at a RESOLUTION (a list of them:
    --resolutions) and may rewrite the page's BLOCK: --scenes, --resolution(s) and --page."""
    parser = ArgumentParser(prog=f"python -m lab {command}", description=doc.splitlines()[0])
    parser.add_argument("--scenes", nargs="+", default=list(scenes))
    if isinstance(resolution, list):
        parser.add_argument("--resolutions", nargs="+", type=parse_resolution, default=resolution)
    else:
        parser.add_argument("--resolution", type=parse_resolution, default=resolution)
    parser.add_argument("--page", help=f"rewrite the {block} block of this markdown page")
    return parser
