"""red: Random Expert Distillation's reward, the driving environment and demo
files, from Python (bindings of the Rust crates red-support, red-drive and
red-core).

>>> import numpy as np, red
>>> demos = red.read_demos("data/drive-scripted-expert.json")  # doctest: +SKIP
>>> obs, act = demos.pairs()                                   # doctest: +SKIP
>>> reward = red.RedReward.fit("rnd", obs, act, seed=0)        # doctest: +SKIP
>>> reward.reward(obs[:5], act[:5])                            # doctest: +SKIP
"""

from ._red import (  # noqa: F401
    RedReward,
    SupportModel,
    TerminalHeuristic,
    __version__,
    default_sigma1_rule,
)
from .convert import (  # noqa: F401
    from_imitation_trajectories,
    from_minari,
    read_imitation,
    read_imitation_npz,
    to_imitation_trajectories,
    write_imitation_npz,
)
from .demos import Demos, Trajectory, read_demos, write_demos  # noqa: F401

try:
    import gymnasium as _gym  # noqa: F401
except ImportError:  # the reward and demo API work without Gymnasium
    pass
else:
    from . import envs, wrappers  # noqa: F401
    from .envs import DriveEnv  # noqa: F401
    from .wrappers import RedRewardVectorWrapper, RedRewardWrapper  # noqa: F401

    envs.register()
