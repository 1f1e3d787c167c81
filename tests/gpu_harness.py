"""Run the chain on synthetic G-buffers (identity view matrix: view space is world space)."""
import numpy as np

CLIP_START, CLIP_END = 0.1, 100.0


def run_synthetic_chain(depth, normal, roughness, projection, settings, radiance=None, state=None,
                        ray_budget=(1.0, 1.0), view_matrix=None, motion=None):
    """Run the chain on the next frame of STATE (default: a still, frame 0); returns
    (outputs as numpy in image order, ChainOutputs)."""
    from ssr_addon.core.chain import ChainState, run_chain
    from ssr_addon.core.gpu_backend import download
    inputs = synthetic_inputs(depth, normal, roughness, projection, radiance, ray_budget, view_matrix, motion)
    state = state or ChainState.still()
    state.begin_frame(0 if state.sequence.frame is None else state.sequence.frame + 1)
    outputs = run_chain(inputs, settings, state)
    arrays = {name: download(outputs[name])
              for name in ("ray_hit", "ray_dir", "ray_stats", "resolved", "spatial", "reflection", "final")}
    if outputs.get("history_record") is not None:
        arrays["history_record"] = download(outputs["history_record"])
    return arrays, outputs


def synthetic_inputs(depth, normal, roughness, projection, radiance=None, ray_budget=(1.0, 1.0), view_matrix=None,
                     motion=None):
    """ChainInputs of a synthetic G-buffer: RADIANCE (default black) is also the combined image,
    the specular colour and F0 are 1, the probe/world reflection 0, MOTION 0 unless given."""
    from ssr_addon.core.gpu_backend import upload
    from ssr_addon.core.inputs import ChainInputs
    height, width = depth.shape
    radiance_tx = upload(np.zeros((height, width, 4), np.float32) if radiance is None else radiance)
    zeros_tx = upload(np.zeros((height, width, 4), np.float32))
    ones_tx = upload(np.ones((height, width, 4), np.float32))
    textures = {"radiance": radiance_tx, "combined": radiance_tx, "depth": upload(depth), "normal": upload(normal),
                "roughness": upload(roughness), "specular_color": ones_tx, "specular_indirect": zeros_tx,
                "f0": ones_tx, "motion": zeros_tx if motion is None else upload(motion)}
    return ChainInputs(textures, view_matrix=np.eye(4, dtype=np.float32) if view_matrix is None else view_matrix,
                       projection_matrix=projection, clip_start=CLIP_START, clip_end=CLIP_END, ray_budget=ray_budget)


def lamp_split_arrays(inputs, settings=None):
    """(specular direct, specular indirect), (H, W, 3) each, of ChainInputs carrying lamps: the
    chain's first pass (its analytic lamp split) on them, read back."""
    from ssr_addon.core.chain import ChainState, FrameRun
    from ssr_addon.core.gpu_backend import download
    from ssr_addon.core.settings import ChainSettings
    run = FrameRun(inputs, settings or ChainSettings(), ChainState.still())
    return tuple(download(run.produced[resource], 3) for resource in ("specular_direct", "specular_indirect"))


def passes_lamp_split(passes):
    """lamp_split_arrays of RenderPasses (lamp_split=analytic)."""
    from ssr_addon.core.inputs import ChainInputs
    from ssr_addon.core.settings import ChainSettings
    return lamp_split_arrays(ChainInputs.from_passes(passes, ChainSettings()))


def lamp_specular(lamps, depth, normal, roughness, view_matrix, projection_matrix):
    """(H, W, 3) unshadowed specular light of LAMPS (core.lamp_split.Lamp) on the surfaces of a
    frame (DEPTH, world NORMAL, ROUGHNESS in image order; the camera's matrices), as the chain
    draws it."""
    from ssr_addon.core.gpu_backend import upload
    inputs = synthetic_inputs(depth, normal, roughness, projection_matrix, view_matrix=view_matrix)
    inputs.textures.update(specular_light=upload(np.zeros_like(normal)), shadow=upload(np.ones_like(depth)))
    inputs.lamps = tuple(lamps)
    return lamp_split_arrays(inputs)[0]
