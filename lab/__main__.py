"""`python -m lab COMMAND [options]`: the lab's measurements (each command's --help says more).

    demo           the end of `make demo`: SSR off and on side by side
    bench          speed against accuracy of every contender, and the stability cases
    error-budget   where the balanced preset's error comes from
    slides         the deck's comparisons, rendered and measured
    chain-stages   each stage's milliseconds at 1600x900, against a copy pass
    memory         resident memory over a long 1600x900 run
    lamps          the lamp splits' cost and error
    live           live SSR's latency from a view change
    crops          balanced stills at 1280x720 beside EEVEE's ray tracing
    captures       what the fallback hierarchy's captures cost, drawn or rendered
"""
import importlib
import sys

from ssr_addon.batch.cli import main
from ssr_addon.core.errors import SSRError

COMMANDS = {"demo": "lab.demo", "bench": "lab.bench.run", "error-budget": "lab.error_budget", "slides": "lab.slides",
            "chain-stages": "lab.chain_stages", "memory": "lab.batch_memory", "lamps": "lab.lamp_split",
            "live": "lab.live_latency", "crops": "lab.still_crops", "captures": "lab.capture_cost"}


def run(argv):
    if not argv or argv[0] not in COMMANDS:
        raise SSRError(f"expected a command, one of {', '.join(COMMANDS)} (python -m lab --help)")
    importlib.import_module(COMMANDS[argv[0]]).main(argv[1:])


if __name__ == "__main__":
    if sys.argv[1:] in (["--help"], ["-h"]):
        print(__doc__)
    else:
        main(sys.argv[1:], command=run)
