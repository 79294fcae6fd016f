#pragma once

// A read-only view of a parsed JSON document that knows where each value sits (its
// file and JSON pointer) and reports every problem as a SceneError naming that place.
// JsonObject additionally remembers which keys were read, so that Finish() can reject
// the keys nobody asked for (pbrt's ReportUnused), suggesting the closest known key.
//
// Only json_value.cpp includes nlohmann/json.hpp: it compiles slowly, and no other file
// needs more than this interface.

#include <cstdint>
#include <memory>
#include <nlohmann/json_fwd.hpp>
#include <optional>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "core/color.h"
#include "core/math.h"

namespace tessera {

class JsonObject;

class JsonValue {
  public:
    const std::string& File() const { return *file_; }
    // RFC 6901 pointer; "" is the whole document.
    const std::string& Pointer() const { return pointer_; }
    // "<file>: <pointer>", the `where` of every SceneError about this value.
    std::string Where() const;
    [[noreturn]] void Fail(const std::string& what) const;

    bool IsNull() const;
    bool IsBool() const;
    bool IsNumber() const;
    bool IsString() const;
    bool IsArray() const;
    bool IsObject() const;
    // "a number", "a string", ... for messages.
    std::string KindName() const;

    bool AsBool() const;
    // Finite and representable as a float.
    float AsFloat() const;
    double AsDouble() const;
    // An integral number within [lo, hi].
    int64_t AsInt(int64_t lo, int64_t hi) const;
    uint64_t AsUint64() const;
    std::string AsString() const;
    // An array of exactly n numbers.
    std::vector<float> AsFloats(size_t n) const;
    Vec3 AsVec3() const { return ToVec3(AsFloats(3)); }
    // An array of three numbers, or one number for grey.
    Rgb AsRgb() const;
    // An array of two numbers, or one number for both.
    Vec2 AsVec2() const;

    // Array access.
    size_t Size() const;
    std::vector<JsonValue> Elements() const;
    // Object access with key tracking; fails unless this is an object.
    JsonObject AsObject() const;

  private:
    friend class JsonDocument;
    friend class JsonObject;
    JsonValue(const nlohmann::ordered_json* j, std::string pointer,
              std::shared_ptr<const std::string> file)
        : j_(j), pointer_(std::move(pointer)), file_(std::move(file)) {}
    JsonValue Child(const std::string& key) const;
    JsonValue Child(size_t index) const;
    static Vec3 ToVec3(const std::vector<float>& v) { return {v[0], v[1], v[2]}; }
    [[noreturn]] void FailType(const std::string& expected) const;

    const nlohmann::ordered_json* j_;
    std::string pointer_;
    std::shared_ptr<const std::string> file_;
};

class JsonObject {
  public:
    const JsonValue& Value() const { return self_; }
    [[noreturn]] void Fail(const std::string& what) const { self_.Fail(what); }
    // The value under `key`, marking it used; nullopt if absent.
    std::optional<JsonValue> Get(const std::string& key);
    // As Get, but an absent key is an error (or, when an unused key is a near miss of
    // `key`, that key is reported as unknown: a typo is the likelier mistake).
    JsonValue Required(const std::string& key);
    bool Has(const std::string& key) const;
    // All keys in file order (marking none used).
    const std::vector<std::string>& Keys() const { return keys_; }
    // Every (key, value) in file order, all marked used: for maps of named records.
    std::vector<std::pair<std::string, JsonValue>> Entries();
    // Fails on the first key that was never read; `what` (e.g. "a sphere") completes
    // the message when no near-miss suggestion exists.
    void Finish(const std::string& what);

  private:
    friend class JsonValue;
    explicit JsonObject(JsonValue self);
    [[noreturn]] void FailUnknown(size_t index, const std::string& what) const;

    JsonValue self_;
    std::vector<std::string> keys_;
    std::vector<bool> used_;
    std::vector<std::string> asked_;  // every key looked up, present or not
};

class JsonDocument {
  public:
    // Reads and parses `path`. A missing or unreadable file, or a syntax error
    // ("<file>:<line>:<col>"), throws a SceneError. Comments (// and /* */) are allowed;
    // a key repeated within one object is an error.
    static JsonDocument Load(const std::string& path);
    // Parses `text` as the contents of `file` (for tests and in-memory scenes).
    static JsonDocument Parse(const std::string& text, const std::string& file);
    JsonDocument(JsonDocument&&) noexcept;
    JsonDocument& operator=(JsonDocument&&) noexcept;
    ~JsonDocument();
    JsonValue Root() const;

  private:
    JsonDocument();
    std::unique_ptr<nlohmann::ordered_json> root_;
    std::shared_ptr<const std::string> file_;
};

// The candidate closest to `word` by edit distance (transpositions count as one edit),
// if close enough to be a plausible typo, else one that `word` abbreviates; "" if none.
std::string ClosestMatch(const std::string& word, const std::vector<std::string>& candidates);
// "a, b or c"
std::string JoinAlternatives(const std::vector<std::string>& words);
// Escapes a key for use in a JSON pointer (RFC 6901: ~ -> ~0, / -> ~1).
std::string EscapePointerToken(const std::string& key);

}  // namespace tessera
