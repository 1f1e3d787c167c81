"""Every section of the slides page, in the deck's order. Each builder takes the run's
SlideContext and returns a section (section.section)."""
from .closing import beyond_the_screen, limits, performance
from .intro import INTRO_SECTIONS
from .resolve import filtered_importance_sampling, importance_sampling, neighbour_reuse, sparse_ray_tracing
from .temporal import reprojection, temporal_filter
from .tracing import cheap_and_expensive_rays, hierarchical_ray_trace, linear_raymarch

SECTIONS = (*INTRO_SECTIONS, linear_raymarch, cheap_and_expensive_rays, hierarchical_ray_trace,
            importance_sampling, neighbour_reuse,
            temporal_filter, reprojection, sparse_ray_tracing, filtered_importance_sampling, performance, limits,
            beyond_the_screen)
