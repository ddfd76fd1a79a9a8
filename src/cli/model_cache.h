// SPDX-License-Identifier: MIT
#pragma once

#include "import/import.h"
#include "prep/prepare.h"

#include <string>

namespace occ::cli {

// The .oss scene for `input`: `input` itself when it is one; for a model file (glTF, OBJ, ...)
// the prepared scene cached beside it (`MODEL.oss`, or under $XDG_CACHE_HOME/occswitch (else
// ~/.cache/occswitch) when its folder is not writable), made with prep's defaults the first
// time and reused while the model's bytes are the same (size and XXH3 hash, recorded in
// `CACHE.source`). Says on stderr what it does. Throws InputError for a model it cannot import.
std::string preparedScene(const std::string& input);

// prep's work (import, progressive meshes, .oss written atomically), shared by `prep` and the
// cache; prints prep's summary line.
void prepareModel(const std::string& input, const std::string& output, const ImportOptions& import = {},
                  const PrepOptions& prep = {}, ReadMode stream = ReadMode::Auto);

}  // namespace occ::cli
