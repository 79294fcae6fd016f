#pragma once

// Errors in user input. A SceneError names where the problem is (file, and a JSON path
// or line) so that a user can find it without reading the renderer's source.

#include <stdexcept>
#include <string>

namespace tessera {

class SceneError : public std::runtime_error {
  public:
    // `where` is "file" or "file: /json/path" or "file:line:col".
    SceneError(const std::string& where, const std::string& what)
        : std::runtime_error(where.empty() ? what : where + ": " + what), where_(where) {}
    const std::string& Where() const { return where_; }

  private:
    std::string where_;
};

}  // namespace tessera
