"""Conformance test suites for plugins, in the optuna style: subclass the suite of your
plugin's kind in your own test module and supply its fixture; pytest collects the inherited
tests. coadapt's built-in plugins use these suites too.

    from coadapt_core.testing import OptimizerConformance

    class TestMyOptimizer(OptimizerConformance):
        @pytest.fixture
        def optimizer_cls(self):
            return MyOptimizer
"""

from coadapt_core.testing.backends import BackendConformance
from coadapt_core.testing.objectives import ObjectiveConformance
from coadapt_core.testing.optimizers import OptimizerConformance
from coadapt_core.testing.robots import RobotConformance
from coadapt_core.testing.simulators import SimulatorConformance

__all__ = [
    "BackendConformance",
    "ObjectiveConformance",
    "OptimizerConformance",
    "RobotConformance",
    "SimulatorConformance",
]
