"""Platform and sensor planning (Hernandez 2004 sec. 3-4; Ramdaras 2010 sec. 4); ``plan``
(:mod:`.planner`) is the PCRLB entry point.
"""

from activetrack.planning.costs import HorizonModel, platform_information
from activetrack.planning.criteria import (
    Criterion,
    criterion_names,
    get_criterion,
    register_criterion,
    unregister_criterion,
)
from activetrack.planning.horizons import HorizonPlan, HorizonStage, SearchSettings, search_horizon
from activetrack.planning.manoeuvre import (
    PlannerPlatform,
    PlatformLimits,
    hold_course,
    manoeuvre_to_unit,
    rollout,
    speed_interval,
    step_platform,
    unit_to_manoeuvre,
)
from activetrack.planning.multisensor import Coordination, PlatformStages, coordinate_platforms
from activetrack.planning.objective import (
    CovarianceTerm,
    InformationTerm,
    Objective,
    Term,
    TrackAggregate,
)
from activetrack.planning.planner import (
    PlannedManoeuvre,
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
    "CovarianceTerm",
    "Criterion",
    "HorizonModel",
    "HorizonPlan",
    "HorizonStage",
    "InformationTerm",
    "Objective",
    "PlanReport",
    "PlanResult",
    "PlanSettings",
    "PlannedManoeuvre",
    "PlannerPlatform",
    "PlatformLimits",
    "PlatformStages",
    "SearchResult",
    "SearchSettings",
    "TargetBelief",
    "Term",
    "TrackAggregate",
    "advance_belief",
    "coordinate_platforms",
    "criterion_names",
    "evolution_search",
    "get_criterion",
    "grid_search",
    "hold_course",
    "manoeuvre_to_unit",
    "plan",
    "platform_information",
    "quadrant_search",
    "register_criterion",
    "rollout",
    "search_horizon",
    "sector_search",
    "speed_interval",
    "step_platform",
    "unit_to_manoeuvre",
    "unregister_criterion",
]
