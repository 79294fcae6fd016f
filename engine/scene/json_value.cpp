#include "scene/json_value.h"

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <nlohmann/json.hpp>
#include <sstream>
#include <unordered_set>

#include "core/error.h"

namespace tessera {

using Json = nlohmann::ordered_json;

// ---------------------------------------------------------------------------------------
// Helpers

std::string EscapePointerToken(const std::string& key) {
    std::string out;
    for (char c : key) {
        if (c == '~') {
            out += "~0";
        } else if (c == '/') {
            out += "~1";
        } else {
            out += c;
        }
    }
    return out;
}

namespace {

std::string Lowercase(std::string s) {
    for (char& c : s) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
    return s;
}

// Optimal string alignment distance: Levenshtein plus adjacent transpositions.
size_t EditDistance(const std::string& a, const std::string& b) {
    size_t n = a.size(), m = b.size();
    std::vector<std::vector<size_t>> d(n + 1, std::vector<size_t>(m + 1));
    for (size_t i = 0; i <= n; ++i) d[i][0] = i;
    for (size_t j = 0; j <= m; ++j) d[0][j] = j;
    for (size_t i = 1; i <= n; ++i) {
        for (size_t j = 1; j <= m; ++j) {
            size_t cost = a[i - 1] == b[j - 1] ? 0 : 1;
            d[i][j] = std::min({d[i - 1][j] + 1, d[i][j - 1] + 1, d[i - 1][j - 1] + cost});
            if (i > 1 && j > 1 && a[i - 1] == b[j - 2] && a[i - 2] == b[j - 1])
                d[i][j] = std::min(d[i][j], d[i - 2][j - 2] + 1);
        }
    }
    return d[n][m];
}

std::string FormatWhere(const std::string& file, const std::string& pointer) {
    return pointer.empty() ? file : file + ": " + pointer;
}

}  // namespace

std::string ClosestMatch(const std::string& word, const std::vector<std::string>& candidates) {
    std::string lw = Lowercase(word);
    size_t limit = lw.size() <= 4 ? 1 : (lw.size() <= 8 ? 2 : 3);
    std::string best;
    size_t best_d = limit + 1;
    for (const std::string& c : candidates) {
        // The distance is at least the difference in length: a long key (a stranger's scene
        // may hold megabytes of one) is compared at no cost, never through the full table.
        if (std::max(lw.size(), c.size()) - std::min(lw.size(), c.size()) > limit) continue;
        size_t d = EditDistance(lw, Lowercase(c));
        if (d < best_d && d < c.size()) {
            best = c;
            best_d = d;
        }
    }
    if (best.empty() && lw.size() >= 3) {
        // A shortened key ("lens" for "lens_radius").
        for (const std::string& c : candidates)
            if (Lowercase(c).rfind(lw, 0) == 0) return c;
    }
    return best;
}

std::string JoinAlternatives(const std::vector<std::string>& words) {
    std::string out;
    for (size_t i = 0; i < words.size(); ++i) {
        if (i > 0) out += i + 1 == words.size() ? " or " : ", ";
        out += words[i];
    }
    return out;
}

// ---------------------------------------------------------------------------------------
// JsonValue

std::string JsonValue::Where() const { return FormatWhere(*file_, pointer_); }

void JsonValue::Fail(const std::string& what) const { throw SceneError(Where(), what); }

void JsonValue::FailType(const std::string& expected) const {
    Fail("expected " + expected + ", got " + KindName());
}

bool JsonValue::IsNull() const { return j_->is_null(); }
bool JsonValue::IsBool() const { return j_->is_boolean(); }
bool JsonValue::IsNumber() const { return j_->is_number(); }
bool JsonValue::IsString() const { return j_->is_string(); }
bool JsonValue::IsArray() const { return j_->is_array(); }
bool JsonValue::IsObject() const { return j_->is_object(); }

std::string JsonValue::KindName() const {
    switch (j_->type()) {
        case Json::value_t::null:
            return "null";
        case Json::value_t::boolean:
            return "a boolean";
        case Json::value_t::number_integer:
        case Json::value_t::number_unsigned:
        case Json::value_t::number_float:
            return "a number";
        case Json::value_t::string:
            return "a string";
        case Json::value_t::array:
            return "an array";
        case Json::value_t::object:
            return "an object";
        default:
            return "an unsupported value";
    }
}

bool JsonValue::AsBool() const {
    if (!j_->is_boolean()) FailType("true or false");
    return j_->get<bool>();
}

double JsonValue::AsDouble() const {
    if (!j_->is_number()) FailType("a number");
    double v = j_->get<double>();
    if (!std::isfinite(v)) Fail("number is not finite");
    return v;
}

float JsonValue::AsFloat() const {
    double v = AsDouble();
    if (std::abs(v) > std::numeric_limits<float>::max()) Fail("number is too large");
    return static_cast<float>(v);
}

int64_t JsonValue::AsInt(int64_t lo, int64_t hi) const {
    if (!j_->is_number()) FailType("an integer");
    auto range = [&] {
        Fail("must be between " + std::to_string(lo) + " and " + std::to_string(hi) + ", got " +
             j_->dump());
    };
    if (j_->is_number_unsigned()) {
        uint64_t u = j_->get<uint64_t>();
        if (u > uint64_t(std::numeric_limits<int64_t>::max()) || int64_t(u) > hi || int64_t(u) < lo)
            range();
        return int64_t(u);
    }
    if (j_->is_number_integer()) {
        int64_t v = j_->get<int64_t>();
        if (v < lo || v > hi) range();
        return v;
    }
    double d = j_->get<double>();
    if (!std::isfinite(d) || d != std::floor(d)) FailType("an integer");
    if (d < double(lo) || d > double(hi)) range();
    return int64_t(d);
}

uint64_t JsonValue::AsUint64() const {
    if (j_->is_number_unsigned()) return j_->get<uint64_t>();
    if (j_->is_number_integer() && j_->get<int64_t>() >= 0) return uint64_t(j_->get<int64_t>());
    if (j_->is_number_integer()) Fail("must not be negative, got " + j_->dump());
    FailType("a non-negative integer");
}

std::string JsonValue::AsString() const {
    if (!j_->is_string()) FailType("a string");
    return j_->get<std::string>();
}

std::vector<float> JsonValue::AsFloats(size_t n) const {
    std::string expected = "an array of " + std::to_string(n) + " numbers";
    if (!j_->is_array()) FailType(expected);
    if (j_->size() != n) Fail("expected " + expected + ", got " + std::to_string(j_->size()));
    std::vector<float> out;
    for (size_t i = 0; i < n; ++i) out.push_back(Child(i).AsFloat());
    return out;
}

Rgb JsonValue::AsRgb() const {
    if (j_->is_number()) return Rgb(AsFloat());
    if (!j_->is_array() || j_->size() != 3)
        Fail("expected an RGB colour (an array of 3 numbers, or one number), got " +
             (j_->is_array() ? "an array of " + std::to_string(j_->size()) : KindName()));
    std::vector<float> v = AsFloats(3);
    return {v[0], v[1], v[2]};
}

Vec2 JsonValue::AsVec2() const {
    if (j_->is_number()) return Vec2(AsFloat(), AsFloat());
    if (!j_->is_array() || j_->size() != 2)
        Fail("expected an array of 2 numbers or one number, got " +
             (j_->is_array() ? "an array of " + std::to_string(j_->size()) : KindName()));
    std::vector<float> v = AsFloats(2);
    return {v[0], v[1]};
}

size_t JsonValue::Size() const {
    if (!j_->is_array()) FailType("an array");
    return j_->size();
}

std::vector<JsonValue> JsonValue::Elements() const {
    std::vector<JsonValue> out;
    for (size_t i = 0, n = Size(); i < n; ++i) out.push_back(Child(i));
    return out;
}

JsonObject JsonValue::AsObject() const {
    if (!j_->is_object()) FailType("an object");
    return JsonObject(*this);
}

JsonValue JsonValue::Child(const std::string& key) const {
    return JsonValue(&(*j_)[key], pointer_ + "/" + EscapePointerToken(key), file_);
}

JsonValue JsonValue::Child(size_t index) const {
    return JsonValue(&(*j_)[index], pointer_ + "/" + std::to_string(index), file_);
}

// ---------------------------------------------------------------------------------------
// JsonObject

JsonObject::JsonObject(JsonValue self) : self_(std::move(self)) {
    for (const auto& item : self_.j_->items()) keys_.push_back(item.key());
    used_.assign(keys_.size(), false);
}

std::optional<JsonValue> JsonObject::Get(const std::string& key) {
    if (std::find(asked_.begin(), asked_.end(), key) == asked_.end()) asked_.push_back(key);
    for (size_t i = 0; i < keys_.size(); ++i) {
        if (keys_[i] == key) {
            used_[i] = true;
            return self_.Child(key);
        }
    }
    return std::nullopt;
}

JsonValue JsonObject::Required(const std::string& key) {
    if (std::optional<JsonValue> v = Get(key)) return *v;
    std::vector<std::string> unused;
    for (size_t i = 0; i < keys_.size(); ++i)
        if (!used_[i]) unused.push_back(keys_[i]);
    std::string near = ClosestMatch(key, unused);
    if (!near.empty()) {
        size_t index = size_t(std::find(keys_.begin(), keys_.end(), near) - keys_.begin());
        FailUnknown(index, "");
    }
    throw SceneError(FormatWhere(self_.File(), self_.Pointer() + "/" + EscapePointerToken(key)),
                     "missing required key '" + key + "'");
}

bool JsonObject::Has(const std::string& key) const {
    return std::find(keys_.begin(), keys_.end(), key) != keys_.end();
}

std::vector<std::pair<std::string, JsonValue>> JsonObject::Entries() {
    std::vector<std::pair<std::string, JsonValue>> out;
    for (size_t i = 0; i < keys_.size(); ++i) {
        used_[i] = true;
        out.emplace_back(keys_[i], self_.Child(keys_[i]));
    }
    return out;
}

void JsonObject::Finish(const std::string& what) {
    for (size_t i = 0; i < keys_.size(); ++i)
        if (!used_[i]) FailUnknown(i, what);
}

void JsonObject::FailUnknown(size_t index, const std::string& what) const {
    const std::string& key = keys_[index];
    // Prefer keys that were asked for but are absent: the typo's likely intent.
    std::vector<std::string> absent;
    for (const std::string& a : asked_)
        if (!Has(a)) absent.push_back(a);
    std::string near = ClosestMatch(key, absent);
    if (near.empty()) near = ClosestMatch(key, asked_);
    std::string message = "unknown key '" + key + "'";
    if (!near.empty()) {
        message += " (did you mean '" + near + "'?)";
    } else if (!what.empty() && !asked_.empty()) {
        std::string list;
        for (const std::string& a : asked_) list += (list.empty() ? "" : ", ") + a;
        message += " (keys of " + what + ": " + list + ")";
    }
    self_.Child(key).Fail(message);
}

// ---------------------------------------------------------------------------------------
// JsonDocument

namespace {

// Tracks the path of the value being parsed so that a duplicate key, which nlohmann
// would silently let overwrite the first, is reported with its JSON pointer.
class DuplicateKeyChecker {
  public:
    explicit DuplicateKeyChecker(std::shared_ptr<const std::string> file)
        : file_(std::move(file)) {}

    bool operator()(int /*depth*/, Json::parse_event_t event, Json& parsed) {
        switch (event) {
            case Json::parse_event_t::object_start:
            case Json::parse_event_t::array_start:
                frames_.push_back({event == Json::parse_event_t::array_start, 0, Token(), {}, ""});
                break;
            case Json::parse_event_t::key: {
                Frame& f = frames_.back();
                f.key = parsed.get<std::string>();
                if (!f.keys.insert(f.key).second)
                    throw SceneError(
                        FormatWhere(*file_, Pointer() + "/" + EscapePointerToken(f.key)),
                        "duplicate key '" + f.key + "'");
                break;
            }
            case Json::parse_event_t::object_end:
            case Json::parse_event_t::array_end:
                frames_.pop_back();
                ValueDone();
                break;
            case Json::parse_event_t::value:
                ValueDone();
                break;
        }
        return true;
    }

  private:
    struct Frame {
        bool is_array;
        size_t next_index;
        std::string token;  // this container's token in its parent
        std::unordered_set<std::string> keys;
        std::string key;  // the key whose value is being parsed
    };

    // The token under which a value starting now sits in its parent.
    std::string Token() const {
        if (frames_.empty()) return "";
        const Frame& p = frames_.back();
        return p.is_array ? std::to_string(p.next_index) : EscapePointerToken(p.key);
    }
    std::string Pointer() const {
        std::string out;
        for (size_t i = 1; i < frames_.size(); ++i) out += "/" + frames_[i].token;
        return out;
    }
    void ValueDone() {
        if (!frames_.empty() && frames_.back().is_array) ++frames_.back().next_index;
    }

    std::shared_ptr<const std::string> file_;
    std::vector<Frame> frames_;
};

// nlohmann's parse_error::byte counts the characters read, the offending one included.
std::string LineColumn(const std::string& text, size_t byte) {
    size_t offset = std::min(byte > 0 ? byte - 1 : 0, text.size());
    size_t line = 1, line_start = 0;
    for (size_t i = 0; i < offset; ++i) {
        if (text[i] == '\n') {
            ++line;
            line_start = i + 1;
        }
    }
    return std::to_string(line) + ":" + std::to_string(offset - line_start + 1);
}

// nlohmann's message without its "[json.exception...] parse error at line L, column C: "
// prefix, since the location is reported apart.
std::string ParseErrorText(const std::string& what) {
    size_t col = what.find("column ");
    size_t colon = col == std::string::npos ? std::string::npos : what.find(": ", col);
    if (colon != std::string::npos) return what.substr(colon + 2);
    size_t bracket = what.find("] ");
    return bracket == std::string::npos ? what : what.substr(bracket + 2);
}

}  // namespace

JsonDocument::JsonDocument() = default;
JsonDocument::JsonDocument(JsonDocument&&) noexcept = default;
JsonDocument& JsonDocument::operator=(JsonDocument&&) noexcept = default;
JsonDocument::~JsonDocument() = default;

JsonDocument JsonDocument::Load(const std::string& path) {
    std::error_code ec;
    if (std::filesystem::is_directory(path, ec))
        throw SceneError(path, "is a directory, not a scene file");
    std::ifstream in(path, std::ios::binary);
    if (!in) throw SceneError(path, std::string("cannot open scene file: ") + std::strerror(errno));
    std::ostringstream ss;
    ss << in.rdbuf();
    if (in.bad()) throw SceneError(path, "error reading scene file");
    return Parse(ss.str(), path);
}

JsonDocument JsonDocument::Parse(const std::string& text, const std::string& file) {
    JsonDocument doc;
    doc.file_ = std::make_shared<const std::string>(file);
    DuplicateKeyChecker checker(doc.file_);
    try {
        doc.root_ = std::make_unique<Json>(Json::parse(
            text,
            [&checker](int depth, Json::parse_event_t event, Json& parsed) {
                return checker(depth, event, parsed);
            },
            /*allow_exceptions=*/true, /*ignore_comments=*/true));
    } catch (const Json::parse_error& e) {
        throw SceneError(file + ":" + LineColumn(text, e.byte), ParseErrorText(e.what()));
    } catch (const Json::exception& e) {
        throw SceneError(file, e.what());
    }
    return doc;
}

JsonValue JsonDocument::Root() const { return JsonValue(root_.get(), "", file_); }

}  // namespace tessera
