#pragma once

// Scene import from pbrt-v4 (and pbrt-v3) files. A `.pbrt` file is converted in memory into
// Tessera's JSON scene description (docs/scene-format.md), which the ordinary parser then
// reads: loading, validation, ListSceneFiles, sandboxing and the farm treat it like any
// scene. The subset converted is documented in docs/pbrt-import.md. Whatever the converter
// does not understand (a directive, a parameter, a type) is skipped or approximated and
// reported as "file:line: what" (pbrt's ReportUnused); a syntax error is a SceneError
// naming file:line.
//
// pbrt's camera space is left-handed and Tessera's right-handed: the same numbers would
// render mirrored. The converter mirrors the world (z -> -z, unless the pbrt camera itself
// mirrors), which keeps every image, every surface's facing and every light's direction.

#include <functional>
#include <string>
#include <utility>
#include <vector>

#include "core/error.h"

namespace tessera {

// Reads a file that a pbrt file includes (Include, Import), named as written in the file:
// a relative name resolves against the folder of the scene file that was loaded, as in
// pbrt. Throws std::runtime_error (or SceneError) saying why it cannot.
using PbrtIncludeReader = std::function<std::string(const std::string& written)>;

struct PbrtImport {
    std::string shown;  // the scene file as named in messages
    std::string json;   // the scene in Tessera's format
    // "file:line: what was skipped or approximated", in file order; a message repeated at
    // several places is given once, at its first, with the number of others.
    std::vector<std::string> warnings;
    // Include/Import files as written (relative to the scene file's folder), once each.
    std::vector<std::string> included_files;
    // Where each converted record came from: (JSON pointer, "file:line").
    std::vector<std::pair<std::string, std::string>> origins;

    // `e`, thrown while parsing `json` as the file `shown`, renamed to the pbrt file and
    // line of the record at fault (the converted record's JSON pointer stays in the text).
    SceneError Relocate(const SceneError& e) const;
};

// Whether `path` names a pbrt file (extension ".pbrt", any case).
bool IsPbrtFile(const std::string& path);

// Converts `text`, the contents of the pbrt file named `shown` in messages.
PbrtImport ImportPbrt(const std::string& shown, const std::string& text,
                      const PbrtIncludeReader& read_include);
// Reads the pbrt file `path`, and the files it includes, from the local file system.
PbrtImport ImportPbrt(const std::string& path);

// Logs the import's warnings (spdlog, warn): each distinct message once per process, so
// that a scene parsed several times (its frame range, then the frame) reports once.
void LogPbrtWarnings(const PbrtImport& import);

}  // namespace tessera
