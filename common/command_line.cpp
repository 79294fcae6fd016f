#include "command_line.h"

#include <algorithm>
#include <cctype>
#include <iostream>
#include <stdexcept>

#include "tessera_version.h"

namespace tessera {

namespace {

std::string StripDashes(const std::string& s) {
    const size_t start = s.find_first_not_of('-');
    return start == std::string::npos ? std::string() : s.substr(start);
}

std::string Lower(std::string s) {
    for (char& c : s) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
    return s;
}

// Edits (insertions, deletions, substitutions and swaps of neighbours) from a to b.
size_t EditDistance(const std::string& a, const std::string& b) {
    std::vector<std::vector<size_t>> d(a.size() + 1, std::vector<size_t>(b.size() + 1));
    for (size_t i = 0; i <= a.size(); ++i) d[i][0] = i;
    for (size_t j = 0; j <= b.size(); ++j) d[0][j] = j;
    for (size_t i = 1; i <= a.size(); ++i)
        for (size_t j = 1; j <= b.size(); ++j) {
            const size_t cost = a[i - 1] == b[j - 1] ? 0 : 1;
            d[i][j] = std::min({d[i - 1][j] + 1, d[i][j - 1] + 1, d[i - 1][j - 1] + cost});
            if (i > 1 && j > 1 && a[i - 1] == b[j - 2] && a[i - 2] == b[j - 1])
                d[i][j] = std::min(d[i][j], d[i - 2][j - 2] + 1);
        }
    return d[a.size()][b.size()];
}

std::string Join(const std::vector<std::string>& items, const std::string& separator) {
    std::string out;
    for (const std::string& item : items) out += (out.empty() ? "" : separator) + item;
    return out;
}

// "; did you mean 'a'?", "; did you mean 'a' or 'b'?", or "".
std::string DidYouMean(const std::string& typed, const std::vector<std::string>& candidates) {
    std::vector<std::string> close = Suggestions(typed, candidates);
    if (close.empty()) return {};
    for (std::string& c : close) c = "'" + c + "'";
    std::string last = close.back();
    close.pop_back();
    return "; did you mean " + (close.empty() ? last : Join(close, ", ") + " or " + last) + "?";
}

std::vector<std::string> CommandNames(const CLI::App& app) {
    std::vector<std::string> names;
    for (const CLI::App* sub :
         app.get_subcommands([](const CLI::App* s) { return !s->get_name().empty(); }))
        names.push_back(sub->get_name());
    return names;
}

// "--spp" and "-o" style names of the command's options, the long ones only unless
// `with_short`.
std::vector<std::string> OptionNames(const CLI::App& app, bool with_short) {
    std::vector<std::string> names;
    for (const CLI::Option* opt : app.get_options()) {
        for (const std::string& l : opt->get_lnames()) names.push_back("--" + l);
        if (with_short)
            for (const std::string& s : opt->get_snames()) names.push_back("-" + s);
    }
    return names;
}

bool LooksLikeNumber(const std::string& s) {
    long double value = 0;
    return CLI::detail::lexical_cast(s, value);
}

bool IsOption(const std::string& arg) {
    return arg.size() > 1 && arg[0] == '-' && !LooksLikeNumber(arg);
}

// What is wrong with an argument that `command` left over.
std::string LeftOver(const CLI::App& command, const std::string& arg) {
    if (IsOption(arg)) {
        const std::string name = arg.substr(0, arg.find('='));
        // A single dash before a long name ("-spp") is a common slip: compare long names too.
        return "unknown option '" + name + "'" +
               DidYouMean(name, OptionNames(command, name.rfind("--", 0) != 0));
    }
    const std::vector<std::string> commands = CommandNames(command);
    if (!commands.empty() && command.get_subcommands().empty())
        return "unknown command '" + arg + "'" + DidYouMean(arg, commands);
    return "unexpected argument '" + arg + "'";
}

// "a whole number" for CLI11's type name "INT", and so on.
std::string WhatTypeIs(const std::string& type_name) {
    const std::string type = type_name.substr(0, type_name.find(':'));
    if (type == "INT" || type == "UINT") return "a whole number";
    if (type == "FLOAT" || type == "NUMBER") return "a number";
    return "a valid value";
}

// CLI11's message, reworded where it is raw.
std::string ErrorText(const CLI::App& command, const CLI::ParseError& error) {
    const std::string what = error.what();
    const std::string kind = error.get_name();
    if (kind == "RequiredError" && what.rfind("A subcommand", 0) == 0)
        return "a command is required: " + Join(CommandNames(command), ", ");
    if (kind == "RequiredError") {
        // "--coordinator is required": say where else it may come from.
        const CLI::Option* opt = command.get_option_no_throw(what.substr(0, what.find(' ')));
        if (opt && !opt->get_envname().empty()) return what + " (or $" + opt->get_envname() + ")";
    }
    if (kind == "ValidationError") {
        // Our checks say "must ...": "--spp: must be" reads "--spp must be".
        const size_t colon = what.find(": must ");
        if (colon != std::string::npos && what.find(": ") == colon)
            return what.substr(0, colon) + what.substr(colon + 1);
        return what;
    }
    if (kind == "ConversionError" && what.rfind("Could not convert: ", 0) == 0) {
        const std::string rest = what.substr(std::string("Could not convert: ").size());
        const size_t eq = rest.find(" = ");
        if (eq != std::string::npos) {
            const std::string name = rest.substr(0, eq), value = rest.substr(eq + 3);
            const CLI::Option* opt = command.get_option_no_throw(name);
            return name + " must be " + WhatTypeIs(opt ? opt->get_type_name() : "") + ", got '" +
                   value + "'";
        }
    }
    if (kind == "ArgumentMismatch" && what.size() > 8 &&
        what.compare(what.size() - 8, 8, " missing") == 0) {
        const size_t colon = what.find(':');
        if (colon != std::string::npos) return what.substr(0, colon) + " needs a value";
    }
    return what;
}

}  // namespace

const char* TesseraVersion() { return kTesseraVersion; }

void AddVersionFlag(CLI::App& app, const std::string& program) {
    app.set_version_flag("--version", program + " " + TesseraVersion(),
                         "Print the version and exit");
}

std::optional<int> ParseCommandLine(CLI::App& app, const std::string& program, int argc,
                                    const char* const* argv) {
    app.name(program);
    try {
        app.parse(argc, argv);
    } catch (const CLI::ParseError& e) {
        const std::string kind = e.get_name();
        // A command's own exit status (`tessera watch`: 3 for a failed job), said already.
        if (kind == "RuntimeError") return e.get_exit_code();
        if (kind == "CallForHelp" || kind == "CallForAllHelp" || kind == "CallForVersion" ||
            kind == "Success")
            return app.exit(e);
        std::cerr << UsageErrorMessage(app, program, e) << std::flush;
        return kExitUsage;
    }
    return std::nullopt;
}

std::string UsageErrorMessage(const CLI::App& app, const std::string& program,
                              const CLI::ParseError& error) {
    // Unknown commands and options first: CLI11 often reports what they caused instead
    // (a missing subcommand, a value taken for a positional argument).
    std::vector<std::string> lines;
    std::string path = program;
    const CLI::App* command = &app;
    for (;;) {
        bool after_unknown_option = false;
        for (const std::string& arg : command->remaining(false)) {
            // The value of an unknown option ("--spd 4") is no news of its own.
            const bool option = IsOption(arg);
            if (!option && after_unknown_option) {
                after_unknown_option = false;
                continue;
            }
            after_unknown_option = option && arg.find('=') == std::string::npos;
            const std::string problem = LeftOver(*command, arg);
            lines.push_back(path + ": " + problem);
            // What follows an unknown command is its arguments.
            if (problem.rfind("unknown command", 0) == 0) break;
        }
        const std::vector<CLI::App*> parsed = command->get_subcommands();
        if (parsed.empty()) break;
        command = parsed.back();
        path += " " + command->get_name();
    }
    if (lines.empty()) lines.push_back(path + ": " + ErrorText(*command, error));
    lines.push_back("See '" + path + " --help'.");
    return Join(lines, "\n") + "\n";
}

std::vector<std::string> Suggestions(const std::string& typed,
                                     const std::vector<std::string>& candidates) {
    const std::string word = Lower(StripDashes(typed));
    if (word.size() < 2) return {};
    // Close: a third of the word's letters wrong at most (at least one, at most three), and
    // never every letter.
    const size_t allowed = std::clamp<size_t>(word.size() / 3, 1, 3);
    std::vector<std::pair<size_t, std::string>> close;
    std::vector<std::string> extending;
    for (const std::string& candidate : candidates) {
        const std::string other = Lower(StripDashes(candidate));
        if (other.empty()) continue;
        const size_t d = EditDistance(word, other);
        if (d <= allowed && d < word.size())
            close.emplace_back(d, candidate);
        else if (word.size() >= 3 && other.rfind(word, 0) == 0)
            extending.push_back(candidate);
    }
    std::sort(close.begin(), close.end());
    std::vector<std::string> out;
    for (const auto& [d, candidate] : close)
        if (d == close.front().first && out.size() < 3 &&
            std::find(out.begin(), out.end(), candidate) == out.end())
            out.push_back(candidate);
    if (out.empty() && extending.size() == 1) out = extending;
    return out;
}

namespace command_line_detail {

CLI::Validator NumberCheck(const Number& type, std::optional<Bound> min, bool min_exclusive,
                           std::optional<Bound> max) {
    const bool integer = type.integer;
    std::string wanted, description;
    if (min && max) {
        wanted = min_exclusive ? "greater than " + min->text + " and at most " + max->text
                               : "from " + min->text + " to " + max->text;
        description = (min_exclusive ? "(" : "[") + min->text + ", " + max->text + "]";
    } else if (min) {
        wanted = (min_exclusive ? "greater than " : "at least ") + min->text;
        description = (min_exclusive ? "> " : ">= ") + min->text;
    } else if (max) {
        wanted = "at most " + max->text;
        description = "<= " + max->text;
    }
    return CLI::Validator(
        [=](std::string& text) -> std::string {
            long double value = 0;
            bool read = false;
            if (integer) {
                long long whole = 0;
                read = CLI::detail::lexical_cast(text, whole);
                value = static_cast<long double>(whole);
            } else {
                read = CLI::detail::lexical_cast(text, value);
            }
            if (!read)
                return fmt::format("must be {} ({}), got '{}'",
                                   integer ? "a whole number" : "a number", wanted, text);
            const bool low = min && !(min_exclusive ? value > min->value : value >= min->value);
            const bool high = max && !(value <= max->value);
            if (low || high || value != value)
                return fmt::format("must be {}, got {}", wanted, text);
            // Beyond what the option's type holds, though within the bounds asked for.
            if (value > type.highest.value)
                return fmt::format("must be at most {}, got {}", type.highest.text, text);
            if (value < type.lowest.value)
                return fmt::format("must be at least {}, got {}", type.lowest.text, text);
            return std::string();
        },
        description);
}

}  // namespace command_line_detail

CLI::Validator OneOf(std::vector<std::string> values) {
    const std::string description = "{" + Join(values, ",") + "}";
    return CLI::Validator(
        [values](std::string& text) -> std::string {
            if (std::find(values.begin(), values.end(), text) != values.end()) return {};
            return "must be one of " + Join(values, ", ") + "; got '" + text + "'" +
                   DidYouMean(text, values);
        },
        description);
}

std::string WithDefaultPort(const std::string& address) {
    if (address.empty()) throw std::invalid_argument("the address is empty");
    for (const char* scheme : {"dns:", "unix:", "unix-abstract:", "ipv4:", "ipv6:", "vsock:"})
        if (address.rfind(scheme, 0) == 0) return address;
    const std::string default_port = ":" + std::to_string(kDefaultPort);
    std::string port;
    if (address[0] == '[') {
        const size_t close = address.find(']');
        if (close == std::string::npos)
            throw std::invalid_argument("'" + address + "' has no ']' after its IPv6 address");
        if (close + 1 == address.size()) return address + default_port;
        if (address[close + 1] != ':')
            throw std::invalid_argument("'" + address + "': expected ':PORT' after ']'");
        port = address.substr(close + 2);
    } else {
        const size_t colon = address.find(':');
        if (colon == std::string::npos) return address + default_port;
        // Two colons or more, no brackets: an IPv6 address alone.
        if (address.find(':', colon + 1) != std::string::npos)
            return "[" + address + "]" + default_port;
        port = address.substr(colon + 1);
    }
    if (port.empty() || port.size() > 5 ||
        port.find_first_not_of("0123456789") != std::string::npos || std::stoi(port) > 65535)
        throw std::invalid_argument("'" + port + "' in '" + address +
                                    "' is not a port number (0 to 65535)");
    return address;
}

CLI::Validator HostAndPort() {
    return CLI::Validator(
        [](std::string& text) -> std::string {
            try {
                text = WithDefaultPort(text);
                return {};
            } catch (const std::invalid_argument& e) {
                return std::string("must be HOST or HOST:PORT: ") + e.what();
            }
        },
        "HOST[:PORT]");
}

CLI::Option* AddCoordinatorAddressOption(CLI::App& app, std::string& address) {
    return app
        .add_option(
            "--coordinator", address,
            "The coordinator's HOST:PORT (port " + std::to_string(kDefaultPort) + " if HOST alone)")
        ->envname("TESSERA_COORDINATOR")
        ->required()
        ->transform(HostAndPort());
}

}  // namespace tessera
