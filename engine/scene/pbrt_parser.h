#pragma once

// Reading pbrt files for the converter (scene/pbrt_import.h): tokens with their file and
// line, typed parameter lists ("type name" value or [ values ]) checked against their type,
// and the report of what a conversion skipped. A parameter that a conversion looks up is
// marked used; ReportUnused names the others with their place, like pbrt's ReportUnused.
// Internal to the converter: everything here is in namespace tessera::pbrt.

#include <cstddef>
#include <initializer_list>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "scene/pbrt_math.h"

namespace tessera::pbrt {

// A place in a pbrt file, for messages.
struct Loc {
    std::shared_ptr<const std::string> file;
    int line = 0;
    std::string Str() const {
        return (file ? *file : std::string("?")) + ":" + std::to_string(line);
    }
};

// Throws the SceneError "file:line: what".
[[noreturn]] void SyntaxError(const Loc& loc, const std::string& what);

// --- tokens

struct Token {
    std::string text;  // a string's contents, without quotes, escapes resolved
    bool quoted = false;
    Loc loc;
    bool Is(std::string_view s) const { return !quoted && text == s; }
};

// A bare word that starts a directive (numbers, brackets and booleans do not).
bool IsDirectiveName(const Token& t);

// The tokens of one file: comments and blanks skipped, brackets alone, strings unquoted.
class Tokenizer {
  public:
    Tokenizer(std::shared_ptr<const std::string> file, std::string text)
        : file_(std::move(file)), text_(std::move(text)) {}

    std::optional<Token> Next();

  private:
    std::string ReadString(const Loc& loc);

    std::shared_ptr<const std::string> file_;
    std::string text_;
    size_t pos_ = 0;
    int line_ = 1;
};

// The tokens of a file and the files it includes, in reading order.
class TokenStream {
  public:
    void Push(Tokenizer t) { files_.push_back(std::move(t)); }
    size_t Depth() const { return files_.size(); }

    const Token* Peek();
    // The next token; at the end of the input, a syntax error at `from` saying `expected`.
    Token Next(const Loc& from, const std::string& expected);

  private:
    std::vector<Tokenizer> files_;
    std::optional<Token> ahead_;
};

// A whole token as a finite number ("+1.5" included).
bool ParseNumber(const std::string& s, double* out);

// --- parameter lists

// One parameter, its values in the member its type uses: numbers (integer, float, point2/3,
// vector2/3, normal3, rgb, xyz, blackbody, and a spectrum given as one constant or as
// (wavelength, value) pairs), strings (string, texture, and a spectrum given by name or
// .spd file) or bools.
struct Param {
    std::string type, name;  // pbrt-v3's type names are read as pbrt-v4's
    Loc loc;
    std::vector<double> numbers;
    std::vector<std::string> strings;
    std::vector<bool> bools;
    bool used = false;
};

// A directive's parameters. Every lookup marks what it finds used.
class ParamSet {
  public:
    std::vector<Param> params;

    // The last parameter `name` of one of `types`, marked used with every other of that
    // name and those types; nullptr if none.
    Param* Get(const std::string& name, std::initializer_list<std::string_view> types);
    // Whether any parameter is called `name`, whatever its type (marks nothing used).
    bool Has(const std::string& name) const;

    // The first value of parameter `name` of the named type, or `def`.
    double Float(const std::string& name, double def);
    int Int(const std::string& name, int def);
    bool Bool(const std::string& name, bool def);
    std::string String(const std::string& name, const std::string& def = "");
    V3 Point(const std::string& name, const V3& def);  // a point3
    // All the numbers of parameter `name` of one of `types`; nullptr if none.
    const std::vector<double>* Numbers(const std::string& name,
                                       std::initializer_list<std::string_view> types);

    void MarkAllUsed();
};

// The parameter list that follows a directive's positional arguments (possibly empty).
ParamSet ReadParams(TokenStream& in);

// --- reporting

// What a conversion skipped or approximated: each distinct message once, at its first
// place, with the number of other places.
class Warnings {
  public:
    void Add(const Loc& loc, const std::string& what);
    // "file:line: what", or "file:line: what (and N more)", in the order first given.
    std::vector<std::string> Lines() const;

  private:
    struct Entry {
        std::string where, what;
        int more = 0;
    };
    std::vector<Entry> entries_;
    std::map<std::string, size_t> index_;  // message -> its entry
};

// Warns of every parameter of `ps` that no lookup used, naming `directive`.
void ReportUnused(const ParamSet& ps, const std::string& directive, Warnings& warnings);

}  // namespace tessera::pbrt
