"""Registers the test plugins (:mod:`plugins_for_tests`) on import: the module a scenario
names in ``plugins: [plugin_registration]``, so that every process that loads it (a ROS node,
a Monte Carlo worker) knows the ``position_fix`` sensor kind and the ``pda_kf`` filter."""

import plugins_for_tests

plugins_for_tests.register()
