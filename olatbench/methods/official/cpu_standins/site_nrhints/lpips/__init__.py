"""Stand-in for lpips in a nrhints-official job with device=cpu
(olatbench.methods.official.cpu_standins.lpips): only ``lpips.LPIPS``; any other name raises
AttributeError (ImportError from ``from lpips import ...``)."""

from olatbench.methods.official.cpu_standins.lpips import LPIPS


def __getattr__(name):
    raise AttributeError(
        f"lpips stand-in (olatbench CPU): lpips.{name} is not provided, only lpips.LPIPS"
    )


__all__ = ["LPIPS"]
