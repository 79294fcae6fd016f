// tessera cert ca     --dir D                      D/ca.pem, D/ca.key
// tessera cert server --dir D --host H [--host H]  D/server.pem, D/server.key (signed by D/ca)
// tessera cert client --dir D --name N             D/N.pem, D/N.key (mutual TLS for workers)
// tessera token --role client|worker --name N --tokens FILE [--out F] [--max-spp S ...]
//
// Keys and tokens are written with mode 0600, atomically (a temporary file, then a
// rename), and never over an existing file unless --force.

#include "security_commands.h"

#include <fcntl.h>
#include <spdlog/spdlog.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <memory>
#include <optional>
#include <stdexcept>

#include "certificates.h"
#include "command_line.h"
#include "security.h"

namespace tessera {
namespace {

namespace fs = std::filesystem;

void WriteFile(const fs::path& path, const std::string& text, mode_t mode, bool force) {
    if (!force && fs::exists(path))
        throw std::runtime_error(path.string() + " exists; pass --force to replace it");
    const std::string temp = path.string() + ".tmp." + std::to_string(::getpid());
    int fd = ::open(temp.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, mode);
    if (fd < 0) throw std::runtime_error("cannot write " + temp + ": " + std::strerror(errno));
    ::fchmod(fd, mode);  // whatever the umask
    size_t done = 0;
    while (done < text.size()) {
        const ssize_t n = ::write(fd, text.data() + done, text.size() - done);
        if (n < 0) {
            const int err = errno;
            ::close(fd);
            ::unlink(temp.c_str());
            throw std::runtime_error("cannot write " + temp + ": " + std::strerror(err));
        }
        done += static_cast<size_t>(n);
    }
    if (::fsync(fd) != 0 || ::close(fd) != 0) {
        ::unlink(temp.c_str());
        throw std::runtime_error("cannot write " + temp);
    }
    fs::rename(temp, path);
}

KeyAndCertificate ReadCa(const fs::path& dir) {
    return {ReadTextFile((dir / "ca.key").string()), ReadTextFile((dir / "ca.pem").string())};
}

struct CertOptions {
    std::string dir;
    std::string name;
    std::vector<std::string> hosts;
    int days = 0;
    bool force = false;
};

void AddCommonCertOptions(CLI::App& cmd, CertOptions& o, int days) {
    o.days = days;
    cmd.add_option("--dir", o.dir, "Folder of the CA (ca.pem, ca.key) and of the new files")
        ->required();
    cmd.add_option("--days", o.days, "Days the certificate is valid")
        ->capture_default_str()
        ->check(InRange(1, 36500));
    cmd.add_flag("--force", o.force, "Replace existing files");
}

}  // namespace

void AddCertCommand(CLI::App& app) {
    CLI::App* cert = app.add_subcommand(
        "cert", "Make a small certificate authority and TLS certificates for a farm");
    cert->require_subcommand(1);

    auto ca_opts = std::make_shared<CertOptions>();
    CLI::App* ca = cert->add_subcommand("ca", "Create the farm's CA: DIR/ca.pem and DIR/ca.key");
    AddCommonCertOptions(*ca, *ca_opts, 3650);
    ca_opts->name = "Tessera farm CA";
    ca->add_option("--name", ca_opts->name, "The CA's common name")->capture_default_str();
    ca->callback([ca_opts] {
        fs::create_directories(ca_opts->dir);
        KeyAndCertificate made = MakeCertificateAuthority(ca_opts->name, ca_opts->days);
        const fs::path dir = ca_opts->dir;
        WriteFile(dir / "ca.key", made.key_pem, 0600, ca_opts->force);
        WriteFile(dir / "ca.pem", made.certificate_pem, 0644, ca_opts->force);
        spdlog::info(
            "wrote {} (give it to every worker and client as --tls-ca) and {} (keep "
            "it secret)",
            (dir / "ca.pem").string(), (dir / "ca.key").string());
    });

    auto server_opts = std::make_shared<CertOptions>();
    CLI::App* server = cert->add_subcommand(
        "server", "A certificate for the coordinator: DIR/server.pem, DIR/server.key");
    AddCommonCertOptions(*server, *server_opts, 825);
    server->add_option("--host", server_opts->hosts,
                       "A name or IP address clients use to reach the coordinator (repeatable; "
                       "localhost and 127.0.0.1 are always included)");
    server->callback([server_opts] {
        std::vector<std::string> names = {"localhost", "127.0.0.1", "::1"};
        for (const std::string& h : server_opts->hosts)
            if (std::find(names.begin(), names.end(), h) == names.end()) names.push_back(h);
        const fs::path dir = server_opts->dir;
        const std::string cn = server_opts->hosts.empty() ? "localhost" : server_opts->hosts[0];
        KeyAndCertificate made = MakeCertificate(ReadCa(dir), cn, names, server_opts->days);
        WriteFile(dir / "server.key", made.key_pem, 0600, server_opts->force);
        WriteFile(dir / "server.pem", made.certificate_pem, 0644, server_opts->force);
        spdlog::info("wrote {} and {}: tessera-coordinator --tls-cert {} --tls-key {}",
                     (dir / "server.pem").string(), (dir / "server.key").string(),
                     (dir / "server.pem").string(), (dir / "server.key").string());
    });

    auto client_opts = std::make_shared<CertOptions>();
    CLI::App* client = cert->add_subcommand(
        "client", "A client certificate (mutual TLS, for workers): DIR/NAME.pem, DIR/NAME.key");
    AddCommonCertOptions(*client, *client_opts, 825);
    client->add_option("--name", client_opts->name, "The certificate's name, e.g. the worker's")
        ->required();
    client->callback([client_opts] {
        for (char c : client_opts->name)
            if (!std::isalnum(static_cast<unsigned char>(c)) && c != '.' && c != '_' && c != '-')
                throw std::invalid_argument("--name may contain only A-Z a-z 0-9 . _ -");
        const fs::path dir = client_opts->dir;
        KeyAndCertificate made =
            MakeCertificate(ReadCa(dir), client_opts->name, {}, client_opts->days);
        WriteFile(dir / (client_opts->name + ".key"), made.key_pem, 0600, client_opts->force);
        WriteFile(dir / (client_opts->name + ".pem"), made.certificate_pem, 0644,
                  client_opts->force);
        spdlog::info(
            "wrote {0}.pem and {0}.key in {1}: tessera-worker --tls-cert ... --tls-key ...",
            client_opts->name, dir.string());
    });
}

void AddTokenCommand(CLI::App& app) {
    struct TokenOptions {
        std::string role, name, tokens, out;
        std::optional<int> max_spp, max_resolution, max_frames, max_priority;
        bool force = false;
    };
    auto o = std::make_shared<TokenOptions>();
    CLI::App* cmd = app.add_subcommand(
        "token",
        "Make an access token: a line in the coordinator's --tokens file, and the "
        "token for the client or worker (--out, else stdout)");
    cmd->add_option("--role", o->role, "client (submit, watch, cancel, fetch) or worker")
        ->required()
        ->check(OneOf({"client", "worker"}));
    cmd->add_option("--name", o->name, "Who holds it (shown in the coordinator's log)")->required();
    cmd->add_option("--tokens", o->tokens, "The coordinator's token file (appended to)")
        ->required();
    cmd->add_option("--out", o->out, "Write the token here (mode 0600) for --token-file");
    cmd->add_flag("--force", o->force, "Replace --out if it exists");
    cmd->add_option("--max-spp", o->max_spp, "Client limit: samples per pixel")->check(AtLeast(1));
    cmd->add_option("--max-resolution", o->max_resolution, "Client limit: pixels per axis")
        ->check(AtLeast(1));
    cmd->add_option("--max-frames", o->max_frames, "Client limit: frames per job")
        ->check(AtLeast(1));
    cmd->add_option("--max-priority", o->max_priority, "Client limit: highest job priority")
        ->check(InRange(-1000, 1000));
    cmd->callback([o] {
        for (char c : o->name)
            if (!std::isalnum(static_cast<unsigned char>(c)) && c != '.' && c != '_' && c != '-')
                throw std::invalid_argument("--name may contain only A-Z a-z 0-9 . _ -");
        std::string limits;
        auto add = [&](const char* key, const std::optional<int>& v) {
            if (v) limits += std::string(" ") + key + "=" + std::to_string(*v);
        };
        add("max_spp", o->max_spp);
        add("max_resolution", o->max_resolution);
        add("max_frames", o->max_frames);
        add("max_priority", o->max_priority);
        if (!limits.empty() && o->role == "worker")
            throw std::invalid_argument("limits apply to client tokens only");
        const std::string token = NewToken();
        if (!o->out.empty()) WriteFile(o->out, token + "\n", 0600, o->force);
        // Append to the token file, created private.
        int fd = ::open(o->tokens.c_str(), O_WRONLY | O_CREAT | O_APPEND | O_CLOEXEC, 0600);
        if (fd < 0)
            throw std::runtime_error("cannot open " + o->tokens + ": " + std::strerror(errno));
        const std::string line = o->role + " " + o->name + " " + token + limits + "\n";
        const bool ok =
            ::write(fd, line.data(), line.size()) == ssize_t(line.size()) && ::fsync(fd) == 0;
        ::close(fd);
        if (!ok) throw std::runtime_error("cannot append to " + o->tokens);
        if (o->out.empty()) {
            std::printf("%s\n", token.c_str());
        } else {
            spdlog::info("{} token '{}' added to {}; the token is in {} (--token-file)", o->role,
                         o->name, o->tokens, o->out);
        }
    });
}

}  // namespace tessera
