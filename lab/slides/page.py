"""index.html of a slides run: one section per slide, images side by side, captions filled in
from the numbers slides.json holds."""
import html

from ssr_addon.batch.outputs import written_together

_STYLE = """body{font-family:sans-serif;max-width:1400px;margin:2em auto;background:#fafafa;color:#222}
section{margin-bottom:3em}.row{display:flex;flex-wrap:wrap;gap:12px}
figure{margin:0}figure img{width:460px;image-rendering:pixelated;border:1px solid #ccc}
figure img.chart{width:900px;image-rendering:auto}
figcaption{font-size:90%;color:#555}p.caption{max-width:60em}"""


def caption_text(section):
    """The section's caption with its numbers filled in."""
    return section["caption"].format(**section["numbers"])


def write_page(path, report):
    width, height = report["resolution"]
    parts = ["<!doctype html>", "<html><head><meta charset='utf-8'><title>Stochastic SSR: the deck, measured"
             "</title>", f"<style>{_STYLE}</style></head><body>",
             "<h1>Stochastic SSR: the deck's comparisons, rendered and measured</h1>",
             f"<p>{width}x{height}, EEVEE at {report['eevee_samples']} samples; errors against Cycles at "
             f"{report['reference_samples']} samples, on the reflective pixels. Every number is in "
             f"<a href='slides.json'>slides.json</a>.</p>"]
    for section in report["sections"]:
        parts.append(f"<section id='{html.escape(section['id'])}'><h2>{html.escape(section['title'])}</h2>"
                     "<div class='row'>")
        for image in section["images"]:
            parts.append(f"<figure><img class='{html.escape(image['kind'])}' src='{html.escape(image['file'])}' "
                         f"alt='{html.escape(image['label'])}'>"
                         f"<figcaption>{html.escape(image['label'])}</figcaption></figure>")
        parts.append(f"</div><p class='caption'>{html.escape(caption_text(section))}</p></section>")
    parts.append("</body></html>")
    with written_together([path]) as (partial,), open(partial, "w", encoding="utf-8") as stream:
        stream.write("\n".join(parts) + "\n")
