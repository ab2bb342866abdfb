"""Models: one file per family, a ``@dataclass`` config and an ``nn.Module(config)``."""

from dancekit.models.revolution import RevolutionConfig, RevolutionModel

__all__ = ["RevolutionConfig", "RevolutionModel"]
