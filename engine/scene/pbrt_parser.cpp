// Reading pbrt files (scene/pbrt_parser.h): the tokenizer, typed parameter lists and the
// report of what a conversion skipped.

#include "scene/pbrt_parser.h"

#include <algorithm>
#include <cctype>
#include <charconv>
#include <cmath>
#include <set>
#include <utility>

#include "core/error.h"

namespace tessera::pbrt {

[[noreturn]] void SyntaxError(const Loc& loc, const std::string& what) {
    throw SceneError(loc.Str(), what);
}

// ---------------------------------------------------------------------------------------
// Tokens

namespace {

bool IsDelimiter(char c) {
    return c == ' ' || c == '\t' || c == '\n' || c == '\r' || c == '\f' || c == '\v' || c == '[' ||
           c == ']' || c == '"' || c == '#';
}

}  // namespace

bool IsDirectiveName(const Token& t) {
    return !t.quoted && !t.text.empty() && std::isalpha(static_cast<unsigned char>(t.text[0])) &&
           t.text != "true" && t.text != "false";
}

std::optional<Token> Tokenizer::Next() {
    while (pos_ < text_.size()) {
        const char c = text_[pos_];
        if (c == '\n') {
            ++line_;
            ++pos_;
        } else if (c == ' ' || c == '\t' || c == '\r' || c == '\f' || c == '\v') {
            ++pos_;
        } else if (c == '#') {
            while (pos_ < text_.size() && text_[pos_] != '\n') ++pos_;
        } else {
            Token t;
            t.loc = {file_, line_};
            if (c == '[' || c == ']') {
                t.text = std::string(1, c);
                ++pos_;
            } else if (c == '"') {
                t.quoted = true;
                t.text = ReadString(t.loc);
            } else {
                const size_t start = pos_;
                while (pos_ < text_.size() && !IsDelimiter(text_[pos_])) ++pos_;
                t.text = text_.substr(start, pos_ - start);
            }
            return t;
        }
    }
    return std::nullopt;
}

std::string Tokenizer::ReadString(const Loc& loc) {
    std::string s;
    for (++pos_;;) {
        if (pos_ >= text_.size()) SyntaxError(loc, "unterminated string");
        const char c = text_[pos_++];
        if (c == '"') return s;
        if (c == '\n') SyntaxError(loc, "unterminated string (a string ends on its line)");
        if (c != '\\') {
            s += c;
            continue;
        }
        if (pos_ >= text_.size()) SyntaxError(loc, "unterminated string");
        const char e = text_[pos_++];
        switch (e) {
            case 'b':
                s += '\b';
                break;
            case 'f':
                s += '\f';
                break;
            case 'n':
                s += '\n';
                break;
            case 'r':
                s += '\r';
                break;
            case 't':
                s += '\t';
                break;
            case '\\':
            case '\'':
            case '"':
                s += e;
                break;
            default:
                SyntaxError(loc, std::string("unknown escape '\\") + e + "' in a string");
        }
    }
}

const Token* TokenStream::Peek() {
    while (!ahead_ && !files_.empty()) {
        ahead_ = files_.back().Next();
        if (!ahead_) files_.pop_back();
    }
    return ahead_ ? &*ahead_ : nullptr;
}

Token TokenStream::Next(const Loc& from, const std::string& expected) {
    if (!Peek()) SyntaxError(from, "unexpected end of file: expected " + expected);
    Token t = std::move(*ahead_);
    ahead_.reset();
    return t;
}

bool ParseNumber(const std::string& s, double* out) {
    const char* b = s.data();
    const char* e = b + s.size();
    if (b != e && *b == '+') ++b;
    auto r = std::from_chars(b, e, *out);
    return r.ec == std::errc() && r.ptr == e && std::isfinite(*out);
}

// ---------------------------------------------------------------------------------------
// Parameter lists

namespace {

// pbrt-v3's type names as pbrt-v4's.
std::string CanonicalType(const std::string& t) {
    if (t == "point") return "point3";
    if (t == "vector") return "vector3";
    if (t == "normal") return "normal3";
    if (t == "color") return "rgb";
    return t;
}

// One parameter's declaration and values, checked against its type.
Param ReadParam(TokenStream& in, const Token& decl) {
    Param p;
    p.loc = decl.loc;
    {
        std::vector<std::string> words;
        size_t i = 0;
        while (i < decl.text.size()) {
            while (i < decl.text.size() && std::isspace(static_cast<unsigned char>(decl.text[i])))
                ++i;
            const size_t start = i;
            while (i < decl.text.size() && !std::isspace(static_cast<unsigned char>(decl.text[i])))
                ++i;
            if (i > start) words.push_back(decl.text.substr(start, i - start));
        }
        if (words.size() != 2)
            SyntaxError(decl.loc, "expected a parameter declaration \"type name\", got \"" +
                                      decl.text + "\"");
        p.type = CanonicalType(words[0]);
        p.name = words[1];
    }
    static const std::set<std::string> kTypes = {
        "integer", "float", "point2",   "vector2",   "point3", "vector3", "normal3",
        "rgb",     "xyz",   "spectrum", "blackbody", "bool",   "string",  "texture"};
    if (!kTypes.count(p.type))
        SyntaxError(decl.loc, "unknown parameter type '" + p.type + "' in \"" + decl.text + "\"");
    const std::string shown = "parameter \"" + decl.text + "\"";

    std::vector<Token> values;
    const Token* t = in.Peek();
    if (!t || IsDirectiveName(*t) || t->Is("]")) SyntaxError(decl.loc, shown + " has no value");
    if (t->Is("[")) {
        const Token open = in.Next(decl.loc, "values");
        for (;;) {
            const Token* v = in.Peek();
            if (!v) SyntaxError(open.loc, "'[' is never closed");
            if (v->Is("]")) break;
            if (v->Is("[") || IsDirectiveName(*v))
                SyntaxError(open.loc, "'[' is never closed (found '" + v->text + "' at line " +
                                          std::to_string(v->loc.line) + ")");
            values.push_back(in.Next(open.loc, "']'"));
        }
        in.Next(open.loc, "']'");
    } else {
        values.push_back(in.Next(decl.loc, "a value"));
    }

    if (p.type == "bool") {
        for (const Token& v : values) {
            if (v.text != "true" && v.text != "false")
                SyntaxError(v.loc, shown + ": expected true or false, got '" + v.text + "'");
            p.bools.push_back(v.text == "true");
        }
        return p;
    }
    const bool all_strings =
        std::all_of(values.begin(), values.end(), [](const Token& v) { return v.quoted; });
    if (p.type == "string" || p.type == "texture" || (p.type == "spectrum" && all_strings)) {
        if (!all_strings) SyntaxError(decl.loc, shown + ": expected quoted strings");
        for (const Token& v : values) p.strings.push_back(v.text);
        if (p.type == "spectrum" && p.strings.size() != 1)
            SyntaxError(decl.loc, shown + ": expected one spectrum name or file");
        return p;
    }
    for (const Token& v : values) {
        double x;
        if (v.quoted || !ParseNumber(v.text, &x))
            SyntaxError(v.loc, shown + ": expected a number, got '" + v.text + "'");
        p.numbers.push_back(x);
    }
    const size_t n = p.numbers.size();
    size_t arity = 1;
    if (p.type == "point2" || p.type == "vector2") arity = 2;
    if (p.type == "point3" || p.type == "vector3" || p.type == "normal3" || p.type == "rgb" ||
        p.type == "xyz")
        arity = 3;
    if (n % arity != 0)
        SyntaxError(decl.loc, shown + ": " + std::to_string(n) + " numbers, not a multiple of " +
                                  std::to_string(arity));
    if (p.type == "spectrum" && n != 1 && n % 2 != 0)
        SyntaxError(decl.loc, shown + ": expected (wavelength, value) pairs");
    if (p.type == "integer")
        for (double x : p.numbers)
            if (x != std::floor(x)) SyntaxError(decl.loc, shown + ": expected integers");
    return p;
}

}  // namespace

Param* ParamSet::Get(const std::string& name, std::initializer_list<std::string_view> types) {
    Param* found = nullptr;
    for (Param& p : params) {
        if (p.name != name) continue;
        if (std::find(types.begin(), types.end(), p.type) == types.end()) continue;
        p.used = true;
        found = &p;
    }
    return found;
}

bool ParamSet::Has(const std::string& name) const {
    return std::any_of(params.begin(), params.end(),
                       [&](const Param& p) { return p.name == name; });
}

double ParamSet::Float(const std::string& name, double def) {
    Param* p = Get(name, {"float"});
    return p && !p->numbers.empty() ? p->numbers[0] : def;
}

int ParamSet::Int(const std::string& name, int def) {
    Param* p = Get(name, {"integer"});
    return p && !p->numbers.empty() ? int(std::clamp(p->numbers[0], -2e9, 2e9)) : def;
}

bool ParamSet::Bool(const std::string& name, bool def) {
    Param* p = Get(name, {"bool"});
    return p && !p->bools.empty() ? p->bools[0] : def;
}

std::string ParamSet::String(const std::string& name, const std::string& def) {
    Param* p = Get(name, {"string"});
    return p && !p->strings.empty() ? p->strings[0] : def;
}

const std::vector<double>* ParamSet::Numbers(const std::string& name,
                                             std::initializer_list<std::string_view> types) {
    Param* p = Get(name, types);
    return p ? &p->numbers : nullptr;
}

V3 ParamSet::Point(const std::string& name, const V3& def) {
    const std::vector<double>* v = Numbers(name, {"point3"});
    return v && v->size() >= 3 ? V3{(*v)[0], (*v)[1], (*v)[2]} : def;
}

void ParamSet::MarkAllUsed() {
    for (Param& p : params) p.used = true;
}

ParamSet ReadParams(TokenStream& in) {
    ParamSet ps;
    while (const Token* t = in.Peek()) {
        if (!t->quoted) break;
        const Token decl = in.Next(Loc{}, "a parameter");
        ps.params.push_back(ReadParam(in, decl));
    }
    return ps;
}

// ---------------------------------------------------------------------------------------
// Reporting

void Warnings::Add(const Loc& loc, const std::string& what) {
    auto [it, fresh] = index_.emplace(what, entries_.size());
    if (fresh)
        entries_.push_back({loc.Str(), what, 0});
    else
        ++entries_[it->second].more;
}

std::vector<std::string> Warnings::Lines() const {
    std::vector<std::string> lines;
    for (const Entry& e : entries_)
        lines.push_back(e.where + ": " + e.what +
                        (e.more ? " (and " + std::to_string(e.more) + " more)" : ""));
    return lines;
}

void ReportUnused(const ParamSet& ps, const std::string& directive, Warnings& warnings) {
    for (const Param& p : ps.params)
        if (!p.used)
            warnings.Add(p.loc, directive + ": parameter \"" + p.type + " " + p.name +
                                    "\" is not supported; ignored");
}

}  // namespace tessera::pbrt
