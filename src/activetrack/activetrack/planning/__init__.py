"""PCRLB manoeuvre planning (Hernandez 2004 sec. 3-4; Ramdaras 2010 sec. 4).

``plan(platforms, belief, settings, F=..., Q=..., dt=...)`` is the entry point; see
:mod:`activetrack.planning.planner`. Building blocks: the manoeuvre model (``manoeuvre``),
batched PCRLB costs (``costs``), the searches (``searches``), the horizons (``horizons``) and
the multi-platform iteration (``multisensor``). The criteria of every planner (PCRLB planning,
MRE positioning and selection) live in one registry, ``criteria``; MRE positioning and
selection (Ramdaras) in ``selection``.
"""

from activetrack.planning.costs import HorizonModel, criterion_cost, platform_information
from activetrack.planning.criteria import (
    Criterion,
    criterion_names,
    get_criterion,
    register_criterion,
    unregister_criterion,
)
from activetrack.planning.horizons import SearchSettings, optimise_platform
from activetrack.planning.manoeuvre import (
    PlatformLimits,
    hold_course,
    manoeuvre_to_unit,
    rollout,
    speed_interval,
    step_platform,
    unit_to_manoeuvre,
)
from activetrack.planning.multisensor import Coordination, coordinate_platforms
from activetrack.planning.planner import (
    PlannedManoeuvre,
    PlannerPlatform,
    PlanReport,
    PlanResult,
    PlanSettings,
    TargetBelief,
    advance_belief,
    plan,
)
from activetrack.planning.searches import (
    SEARCHES,
    SearchResult,
    evolution_search,
    grid_search,
    quadrant_search,
    sector_search,
)

__all__ = [
    "SEARCHES",
    "Coordination",
    "Criterion",
    "HorizonModel",
    "PlanReport",
    "PlanResult",
    "PlanSettings",
    "PlannedManoeuvre",
    "PlannerPlatform",
    "PlatformLimits",
    "SearchResult",
    "SearchSettings",
    "TargetBelief",
    "advance_belief",
    "coordinate_platforms",
    "criterion_cost",
    "criterion_names",
    "evolution_search",
    "get_criterion",
    "grid_search",
    "hold_course",
    "manoeuvre_to_unit",
    "optimise_platform",
    "plan",
    "platform_information",
    "quadrant_search",
    "register_criterion",
    "rollout",
    "sector_search",
    "speed_interval",
    "step_platform",
    "unit_to_manoeuvre",
    "unregister_criterion",
]
