#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# Host code cannot touch device memory (issue 12, "memory in types"): snippets that read
# through a DevicePtr, index a DeviceArray or hand a kernel host memory must not compile, and
# the same snippet's legal twin must. Also: no host source includes kernels/device_access.h.
#   device_types_compile.sh CXX SOURCE_DIR
set -euo pipefail
cxx=$1 src=$2
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
flags=(-std=c++20 -fsyntax-only -I"$src/kernels" -I"$src/src" -I/usr/include/glm)

compile() {  # compile NAME BODY: 0 when it compiles
  cat > "$tmp/$1.cpp" <<CPP
#include "device_memory.h"
#include "lod_select.h"
#include <vector>
using namespace occ::k;
void probe(DeviceArray<float>& a, DevicePtr<float> p, std::vector<uint32_t>& host, const ObjectInfo* objects) {
  (void)a; (void)p; (void)host; (void)objects;
  $2;
}
CPP
  "$cxx" "${flags[@]}" "$tmp/$1.cpp" 2>"$tmp/$1.log"
}

fail=0
expect() {  # expect ok|error NAME BODY
  if compile "$2" "$3"; then got=ok; else got=error; fi
  if [ "$got" != "$1" ]; then
    echo "FAIL: '$3' should give $1, gave $got"; cat "$tmp/$2.log"; fail=1
  else
    echo "ok: '$3' -> $1"
  fi
}

expect ok    legal_offset   'DevicePtr<const float> q = p + 3; (void)q'
expect ok    legal_copy     'float x = 0; copyToHost(&x, a.ptr(), 1)'
expect error deref          'float x = *p; (void)x'
expect error index_ptr      'float x = p[0]; (void)x'
expect error index_array    'float x = a[0]; (void)x'
expect error data_pointer   'float* x = a.data(); (void)x'
expect ok    legal_kernel   'DeviceArray<float> s; DeviceArray<ObjectInfo> o; DeviceArray<uint32_t> ids; lodSelect(o.ptr(), ids.ptr(), 0, Camera{}, LodParams{}, nullptr, nullptr, nullptr, nullptr, s)'
expect error host_to_kernel 'DeviceArray<float> s; DeviceArray<ObjectInfo> o; lodSelect(o.ptr(), host.data(), 0, Camera{}, LodParams{}, nullptr, nullptr, nullptr, nullptr, s)'
expect error host_objects   'DeviceArray<float> s; DeviceArray<uint32_t> ids; lodSelect(objects, ids.ptr(), 0, Camera{}, LodParams{}, nullptr, nullptr, nullptr, nullptr, s)'

# Only kernel sources may reach the memory behind a DevicePtr.
if grep -rlnE "device_access.h|layout_access.h" "$src/src" "$src/roles" "$src/tests" --include='*.cpp' --include='*.h' | grep -v 'device_types_compile'; then
  echo "FAIL: the files above include kernels/device_access.h"; fail=1
else
  echo "ok: no host source includes device_access.h"
fi
exit $fail
