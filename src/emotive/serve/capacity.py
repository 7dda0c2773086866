"""The admission limit: how many agents one stepping engine can take by its measured cost.

Each engine that steps part of the scene (the simulation thread's own, or one step worker
process) has a :class:`StepCosts`: the processor time of its recent steps at each agent
count. The step's median time at each of the last :data:`COUNTS_FITTED` agent counts is
fitted by a line (a fixed cost plus a cost per agent) once those counts span
:data:`MEASURED_AGENTS`; the limit is where the line crosses the budget (a share of the
frame period), and the present count when the step already takes longer. The scene's limit
is the sum of its engines' limits, at most ``--max-agents``: engines in separate processes
step at once, each within its own budget.
"""

from __future__ import annotations

from collections import OrderedDict, deque

import numpy as np

#: Agent counts whose step times are fitted (the most recent ones).
COUNTS_FITTED = 8
#: The fitted counts must span at least this many agents.
MEASURED_AGENTS = 16
#: Recent steps kept per agent count.
COST_WINDOW = 15


class StepCosts:
    """The measured step times of one engine and the agents they allow.

    Args:
        budget: seconds a step may take with every agent the engine admits.
        ceiling: the most agents it may ever hold (``--max-agents``).
    """

    def __init__(self, budget: float, ceiling: int) -> None:
        self.budget = float(budget)
        self.ceiling = int(ceiling)
        self.limit = int(ceiling)
        self._times: OrderedDict[int, deque[float]] = OrderedDict()

    def measured(self, agents: int, seconds: float) -> int:
        """Take one step of ``agents`` agents in ``seconds`` into the limit; returns it."""
        if agents == 0:
            return self.limit
        times = self._times.setdefault(agents, deque(maxlen=COST_WINDOW))
        times.append(seconds)
        self._times.move_to_end(agents)
        while len(self._times) > COUNTS_FITTED:
            self._times.popitem(last=False)
        counts = np.array(list(self._times), dtype=np.float64)
        medians = np.array([np.median(t) for t in self._times.values()])
        limit = self.ceiling
        if np.median(times) > self.budget:
            limit = agents
        elif len(counts) >= 2 and np.ptp(counts) >= MEASURED_AGENTS:
            slope, fixed = np.polyfit(counts, medians, 1)
            if slope > 0.0:
                limit = min(limit, max(int((self.budget - fixed) / slope), agents))
        self.limit = limit
        return limit
