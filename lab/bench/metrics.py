"""Accuracy: the reflective-pixel mask, FLIP, relative MAE, PSNR and SSIM, the Pareto front, and
the averaging and log formatting of scores."""
import numpy as np

from ssr_addon.core.settings import ChainSettings
from .images import display

# Reflective pixels: inside SSR's roughness range, with a specular colour large
# enough that the reflection is a visible part of the pixel.
MIN_SPECULAR_COLOR = 0.1

ACCURACY_METRICS = ("flip_reflective", "flip_all", "mae_reflective", "psnr_reflective", "psnr_all",
                    "ssim_reflective", "ssim_all")


def reflective_mask(roughness, specular_color):
    return (roughness <= ChainSettings().max_roughness) & (specular_color.max(axis=-1) >= MIN_SPECULAR_COLOR)


def flip_map(reference, image):
    """Per-pixel HDR-FLIP error in [0, 1]; exposures follow the reference."""
    import flip_evaluator
    error, _, _ = flip_evaluator.evaluate(np.ascontiguousarray(np.maximum(reference, 0), np.float32),
                                          np.ascontiguousarray(np.maximum(image, 0), np.float32),
                                          "HDR", applyMagma=False)
    return error[..., 0]


def flip_error(reference, image, mask):
    """Mean FLIP over MASK; None where the mask is empty."""
    return float(flip_map(reference, image)[mask].mean()) if mask.any() else None


def relative_mae(reference, image, mask):
    """Mean absolute error over MASK relative to the reference's mean there; None where empty."""
    if not mask.any():
        return None
    return float(np.abs(image[mask] - reference[mask]).mean() / max(np.abs(reference[mask]).mean(), 1e-6))


def accuracy(reference, image, mask):
    """FLIP, PSNR and SSIM against the reference, on the reflective pixels and the whole image, and
    the relative mean absolute error (linear radiance) on the reflective pixels."""
    from skimage.metrics import structural_similarity
    error = flip_map(reference, image)
    shown_reference, shown = display(reference), display(image)
    _, ssim = structural_similarity(shown_reference, shown, channel_axis=-1, data_range=1.0, full=True,
                                    gaussian_weights=True, sigma=1.5, use_sample_covariance=False)
    squared = ((shown_reference - shown) ** 2).mean(axis=-1)

    def psnr(selection):
        return float(10 * np.log10(1.0 / max(squared[selection].mean(), 1e-12)))
    everywhere = np.ones_like(mask)
    scores = {"mae_reflective": relative_mae(reference, image, mask)}
    for region, selection in (("reflective", mask), ("all", everywhere)):
        empty = not selection.any()
        scores[f"flip_{region}"] = None if empty else float(error[selection].mean())
        scores[f"psnr_{region}"] = None if empty else psnr(selection)
        scores[f"ssim_{region}"] = None if empty else float(ssim.mean(axis=-1)[selection].mean())
    return scores, error


def pareto_front(points):
    """Names of the points no other point beats on both time and error (lower is better)."""
    front = []
    for name, (time_ms, error) in points.items():
        dominated = any(other_time <= time_ms and other_error <= error and (other_time, other_error) != (time_ms, error)
                        for other, (other_time, other_error) in points.items() if other != name)
        if not dominated:
            front.append(name)
    return sorted(front, key=lambda name: points[name][0])


def _mean(values):
    values = [v for v in values if v is not None]
    return float(np.mean(values)) if values else None


def _format(value):
    if value is None:
        return "-"
    if isinstance(value, bool):
        return "yes" if value else "NO"
    if isinstance(value, float):
        return f"{value:.4g}"
    return str(value)
