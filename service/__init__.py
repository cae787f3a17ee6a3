"""The long-running service: Zenoh bus adapter, Rerun streaming, simulator and CLI.

This package will own ``ServiceNode`` (the Zenoh session and the Rerun stream of the bus
contract in FORMATS.md), the unicycle and lidar simulator used by ``tamp-service demo``, and
the ``tamp-service`` command line.

The simulator is in :mod:`service.sim` (``docs/simulator.md``); the bus adapter and the CLI
are not implemented yet: they are delivered by a later issue (see the Status section of the
README). Until then the main job is ``harmonic-tamp-nav`` (``navigation.render``).
"""
