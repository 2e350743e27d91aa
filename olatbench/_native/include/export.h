// The export conventions every olatbench C++ library shares (olatbench/_native builds and loads them).
//
// Functions are plain C (extern "C") on raw pointers and fixed-width integers, so a library depends on no torch
// headers or C++ ABI; Python declares each one's argument and return types once, in its owner's symbol table.
#pragma once

#define OLATBENCH_EXPORT extern "C" __attribute__((visibility("default")))

// OLATBENCH_ABI_VERSION is passed by the build (-DOLATBENCH_ABI_VERSION=<olatbench._native.ABI_VERSION>); the
// loader checks that the library reports it.
#ifndef OLATBENCH_ABI_VERSION
#error "compile through olatbench._native, which defines OLATBENCH_ABI_VERSION"
#endif

// Each library's main source invokes this once: int olatbench_abi_version(void).
#define OLATBENCH_DEFINE_ABI_VERSION() \
  OLATBENCH_EXPORT int olatbench_abi_version() { return OLATBENCH_ABI_VERSION; }
