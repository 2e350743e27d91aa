"""The ``lpips``, ``lpips_alex`` and ``lpips_vgg`` metrics of the registry
(`olatbench.metrics.registry`): one LPIPS pass per batch (`Protocol.lpips_batch`, shared through the
batch's cache), read per network."""

from __future__ import annotations

from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from olatbench.metrics.protocols import Protocol
    from olatbench.metrics.registry import MetricBatch


def _lpips_by_net(batch: MetricBatch, protocol: Protocol) -> dict[str, list[float | None]]:
    """The protocol's LPIPS of the batch per network (`Protocol.lpips_batch`), computed once per
    batch."""
    if "lpips" not in batch.cache:
        batch.cache["lpips"] = protocol.lpips_batch(batch.pred, batch.gt, batch.mask, batch.device)
    return batch.cache["lpips"]


def _of_net(batch: MetricBatch, protocol: Protocol, net: str) -> list[float | None]:
    if net not in protocol.lpips_nets:
        raise ValueError(
            f"protocol {protocol.id} lists lpips_{net} but its LPIPS networks are "
            f"{', '.join(protocol.lpips_nets)}"
        )
    return _lpips_by_net(batch, protocol)[net]


def protocol_lpips(batch: MetricBatch, protocol: Protocol) -> list[float | None]:
    """The ``lpips`` metric: LPIPS of the protocol's primary network (``lpips_primary``)."""
    return _of_net(batch, protocol, protocol.lpips_primary)


def protocol_lpips_alex(batch: MetricBatch, protocol: Protocol) -> list[float | None]:
    """The ``lpips_alex`` metric: LPIPS-AlexNet, as the protocol feeds it."""
    return _of_net(batch, protocol, "alex")


def protocol_lpips_vgg(batch: MetricBatch, protocol: Protocol) -> list[float | None]:
    """The ``lpips_vgg`` metric: LPIPS-VGG16, as the protocol feeds it."""
    return _of_net(batch, protocol, "vgg")
