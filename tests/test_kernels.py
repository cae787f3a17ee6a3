"""The warm-ups tamp-service calls at start-up (navigation.kernels, perception._fit_kernel with
perception._shape_kernel, tamp._segment_kernel, tamp._astar_kernel, tamp._product_kernel) compile every kernel the construction, the navigation function, the
simulator's lidar, the obstacle map, the roadmap, the harmonic trees and the planner use: afterwards, building and evaluating
forests of random and shared worlds, scanning with the lidar, updating an obstacle map,
building a roadmap, planning a tree and a mission compile nothing new (checked in a fresh process)."""

import json
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent

SCRIPT = r"""
import json
import numpy as np
import navigation
import navigation.forest as F
import perception._fit_kernel as fit_kernel
import perception._shape_kernel as shape_kernel
import tamp._segment_kernel as segment_kernel
import tamp._astar_kernel as astar_kernel
import tamp._product_kernel as product_kernel
from navigation.kernels import compiled_signatures, warm_up
from perception import ObstacleMap
from service.sim import Simulator
from tests.worldgen import random_forest_world

warm_up()
fit_kernel.warm_up()
segment_kernel.warm_up()
astar_kernel.warm_up()
product_kernel.warm_up()
kernels = (fit_kernel, shape_kernel, segment_kernel, astar_kernel, product_kernel)
before = compiled_signatures(kernels)
worlds = [random_forest_world(seed, n_obstacles=n, max_depth=4) for seed, n in ((0, 8), (1, 15), (2, 25))]
worlds += [navigation.load_world(name) for name in ("office", "cluttered20")]
for w in worlds:
    F.clear_cache()
    forest = w.forest(0.0)
    forest.distances, forest.wall_distance
    goal = list(w.regions.values())[0].center
    nf = navigation.NavigationFunction(forest, goal)
    nf.evaluate(np.asarray(goal)[None] + 0.05, 2)
    nf.evaluate(np.asarray(goal) + 0.05, 2)
    navigation.OrientedField(nf, 0.3).evaluate(np.asarray(goal) + 0.1)  # the controller's field
office = navigation.load_world("office")
sim = Simulator(office, seed=0)
omap = ObstacleMap.from_world(office)
for k in range(40):
    sim.step((0.3, 0.4))
    omap.update_scan(sim.scan_message(), sim.pose_message())
from tamp.roadmap import Roadmap
from tamp.harmonic_tree import plan_tree
rm = Roadmap.from_world(office)
c = [r.center for r in office.regions.values()]
plan_tree(rm, (*c[0], 0.0), (*c[1], 1.0))
from tamp.planner import MissionPlanner
MissionPlanner("office").plan()
after = compiled_signatures(kernels)
print(json.dumps({k: [before.get(k), v] for k, v in after.items() if before.get(k) != v}))
"""


def test_warm_up_compiles_everything_used():
    out = subprocess.run([sys.executable, "-c", SCRIPT], cwd=ROOT, capture_output=True, text=True, timeout=600)
    assert out.returncode == 0, out.stderr[-2000:]
    assert json.loads(out.stdout.strip().splitlines()[-1]) == {}
