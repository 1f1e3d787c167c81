"""Run the chain on synthetic G-buffers (identity view matrix: view space is world space)."""
import numpy as np

CLIP_START, CLIP_END = 0.1, 100.0


def run_synthetic_chain(depth, normal, roughness, projection, settings, radiance=None, state=None,
                        ray_budget=(1.0, 1.0), view_matrix=None, motion=None):
    """Run the chain on the next frame of STATE (default: a still, frame 0); returns
    (outputs as numpy in image order, ChainOutputs)."""
    from ssr_addon.chain import ChainInputs, ChainState, run_chain
    from ssr_addon.gpu_backend import download, upload
    height, width = depth.shape
    if radiance is None:
        radiance = np.zeros((height, width, 4), np.float32)
    radiance_tx = upload(radiance)
    zeros_tx = upload(np.zeros((height, width, 4), np.float32))
    ones_tx = upload(np.ones((height, width, 4), np.float32))
    inputs = ChainInputs(
        radiance_tx=radiance_tx, depth_tx=upload(depth), normal_tx=upload(normal),
        roughness_tx=upload(roughness), combined_tx=radiance_tx, specular_color_tx=ones_tx,
        specular_indirect_tx=zeros_tx, f0_tx=ones_tx, motion_tx=zeros_tx if motion is None else upload(motion), view_matrix=np.eye(4, dtype=np.float32) if view_matrix is None else view_matrix,
        projection_matrix=projection, clip_start=CLIP_START, clip_end=CLIP_END, ray_budget=ray_budget)
    state = state or ChainState.still()
    state.begin_frame(0 if state.sequence.frame is None else state.sequence.frame + 1)
    outputs = run_chain(inputs, settings, state)
    arrays = {name: download(getattr(outputs, f"{name}_tx"))
              for name in ("ray_hit", "ray_dir", "ray_stats", "resolved", "spatial", "reflection", "final")}
    if outputs.history_count_tx is not None:
        arrays["history_count"] = download(outputs.history_count_tx)
    return arrays, outputs
