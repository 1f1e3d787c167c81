"""What the screen could not resolve in a frame, and why: the ray outcomes (uniforms.RAY_OUTCOMES)
of its pixels weighed by the reflected light they miss. The fallback setting's auto choice
and the report read it."""
import numpy as np

from .uniforms import RAY_OUTCOMES

# Why a pixel's reflection fell short of a full one: its ray missed (and why), or it hit but
# was faded (near where the ray leaves the screen, towards the camera, near max_roughness).
MISS_REASONS = ("left_frame", "behind", "escaped", "faded")


def unresolved_shares(outcome, confidence, specular_weight, traced, reaching=None):
    """{reason: share} of the frame's reflected light (SPECULAR_WEIGHT, (H, W), over the TRACED
    pixels) left to the probes and world, by MISS_REASONS: (1 - CONFIDENCE) of each pixel, by
    the OUTCOME (RAY_OUTCOMES code) of its ray. Arrays at the frame's resolution. REACHING
    ((H, W) weights, optional) counts each pixel's that many times: 1 where its ray would
    reach geometry, 0 where not (blender.reflected_rays)."""
    weight = np.where(traced, specular_weight, 0.0)
    total = weight.sum()
    missing = weight * np.clip(1.0 - confidence, 0.0, 1.0) * (1.0 if reaching is None else reaching)
    code = np.rint(outcome).astype(int)
    reasons = {reason: code == RAY_OUTCOMES[reason] for reason in MISS_REASONS[:-1]}
    reasons["faded"] = ~np.logical_or.reduce(list(reasons.values()))
    return {reason: round(float(missing[where].sum() / total), 4) if total > 0 else 0.0
            for reason, where in reasons.items()}
