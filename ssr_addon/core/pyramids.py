"""The chain's two 2x2 reduction pyramids, each packed into one atlas texture: the min-depth
pyramid of the Hi-Z tracer ("Generate Depth Mip-Map: use min values instead of average") and
the colour pyramid of the cone-filtered resolve."""
import math

from .uniforms import MAX_PYRAMID_LEVELS


def pyramid_levels(size):
    """Sizes of a 2x2 reduction pyramid down to 1x1 (ceil halving), at most MAX_PYRAMID_LEVELS."""
    levels = [tuple(size)]
    while max(levels[-1]) > 1 and len(levels) < MAX_PYRAMID_LEVELS:
        width, height = levels[-1]
        levels.append((math.ceil(width / 2), math.ceil(height / 2)))
    return levels


def atlas_layout(levels):
    """(atlas size, per-level rectangles, {parity: column size}): level 0 at the origin, the
    odd levels stacked in a column to its right, the even ones in a column right of that.
    Each column is one copy of the texture its levels are drawn into (build_pyramid), where
    they lie at x = 0 and at the same y."""
    heights, column_y = {1: 0, 0: 0}, []
    for index, (_, height) in enumerate(levels[1:], 1):
        column_y.append(heights[index % 2])
        heights[index % 2] += height
    columns = {1: (levels[1][0] if len(levels) > 1 else 0, heights[1]),
               0: (levels[2][0] if len(levels) > 2 else 0, heights[0])}
    column_x = {1: levels[0][0], 0: levels[0][0] + columns[1][0]}
    rects = [(0, 0, *levels[0])] + [(column_x[index % 2], y, *size)
                                    for index, (y, size) in enumerate(zip(column_y, levels[1:]), 1)]
    return (column_x[0] + columns[0][0], max(levels[0][1], heights[1], heights[0])), rects, columns


def build_pyramid(source_tx, reduction, pack, pool, level_count=None, name=None):
    """Reduce SOURCE level by level with the pass REDUCTION (gpu_passes.HIZ_DOWNSAMPLE: min,
    COLOR_DOWNSAMPLE: mean) and pack the levels into one atlas texture with PACK
    (gpu_passes.PYRAMID_PACK); returns (atlas, rectangles).

    Each level is one draw, into the column texture of its parity, reading the level before
    from the other one (a texture may not be read while drawn into); then three copies make
    the atlas: the source as level 0, and each column. NAME (default: the reduction's) keeps
    its textures in POOL apart from another pyramid's."""
    name = name or reduction.name
    levels = pyramid_levels((source_tx.width, source_tx.height))[:level_count]
    atlas_size, rects, columns = atlas_layout(levels)
    channels = reduction.outputs[0].channels
    atlas = pool.get(f"{name}.atlas", atlas_size, channels)
    column_tx = {parity: pool.get(f"{name}.column{parity}", size, channels)
                 for parity, size in columns.items() if size[1] > 0}
    source, source_rect = source_tx, rects[0]
    for index, (_, y, width, height) in enumerate(rects[1:], 1):
        target, rect = column_tx[index % 2], (0, y, width, height)
        reduction.draw([target], samplers=(("source_tx", source),),
                       constants=(("source_offset", source_rect[:2]), ("source_size", source_rect[2:]),
                                  ("level_offset", rect[:2])), region=rect)
        source, source_rect = target, rect
    first_level = {1: 1, 0: 2}  # of each column: its x in the atlas
    copies = [(source_tx, rects[0])] + [(texture, (rects[first_level[parity]][0], 0, *columns[parity]))
                                        for parity, texture in column_tx.items()]
    for texture, rect in copies:
        pack.draw([atlas], samplers=(("level_tx", texture),), constants=(("level_offset", rect[:2]),), region=rect)
    return atlas, rects
