// A no-op device guard for CUDA, registered in a CPU-only build of torch so that fake CUDA tensors (FakeTensorMode)
// can be indexed, converted and printed: torch's Python bindings open a device guard for a tensor's device before
// they dispatch (THPVariable_getitem, Tensor.item, torch.tensor(..., device=...)), and a CPU-only build has none for
// CUDA ("PyTorch is not linked with support for cuda devices"). A CUDA build without a device gets the same guard
// from torch itself (c10::impl::ensureCUDADeviceGuardSet, which FakeTensorMode calls on entry); this library does
// what that function does where it cannot (it only replaces an already registered CUDA guard).
#include <c10/core/impl/DeviceGuardImplInterface.h>

namespace {
c10::impl::NoOpDeviceGuardImpl<c10::DeviceType::CUDA> fake_cuda_guard;
}

// 1: registered now; 0: a CUDA guard was already registered (a CUDA build of torch), left as it is.
extern "C" int olatbench_register_fake_cuda_guard() {
    if (c10::impl::hasDeviceGuardImpl(c10::DeviceType::CUDA)) {
        return 0;
    }
    c10::impl::device_guard_impl_registry[static_cast<size_t>(c10::DeviceType::CUDA)].store(&fake_cuda_guard);
    return 1;
}
