#include "security.h"

#include <grpcpp/security/credentials.h>
#include <grpcpp/support/client_interceptor.h>
#include <spdlog/spdlog.h>
#include <sys/stat.h>

#include <cstdlib>
#include <fstream>
#include <sstream>
#include <stdexcept>

namespace tessera {
namespace {

std::string Env(const char* name) {
    const char* value = std::getenv(name);
    return value ? std::string(value) : std::string();
}

std::string Trim(const std::string& s) {
    const size_t begin = s.find_first_not_of(" \t\r\n");
    if (begin == std::string::npos) return {};
    const size_t end = s.find_last_not_of(" \t\r\n");
    return s.substr(begin, end - begin + 1);
}

// Adds the token to the initial metadata of every call on the channel.
class TokenInterceptor final : public grpc::experimental::Interceptor {
  public:
    explicit TokenInterceptor(const std::string& header) : header_(header) {}
    void Intercept(grpc::experimental::InterceptorBatchMethods* methods) override {
        if (methods->QueryInterceptionHookPoint(
                grpc::experimental::InterceptionHookPoints::PRE_SEND_INITIAL_METADATA))
            methods->GetSendInitialMetadata()->insert({kAuthorizationKey, header_});
        methods->Proceed();
    }

  private:
    const std::string& header_;
};

class TokenInterceptorFactory final : public grpc::experimental::ClientInterceptorFactoryInterface {
  public:
    explicit TokenInterceptorFactory(std::string token) : header_(kBearerPrefix + token) {}
    grpc::experimental::Interceptor* CreateClientInterceptor(
        grpc::experimental::ClientRpcInfo*) override {
        return new TokenInterceptor(header_);
    }

  private:
    // Lives as long as the channel, which owns its interceptor factories.
    const std::string header_;
};

}  // namespace

std::string ReadTextFile(const std::string& path) {
    std::ifstream in(path, std::ios::binary);
    if (!in) throw std::runtime_error("cannot read " + path);
    std::ostringstream text;
    text << in.rdbuf();
    if (in.bad()) throw std::runtime_error("cannot read " + path);
    return text.str();
}

std::string ReadSecretFile(const std::string& path) {
    std::string secret = Trim(ReadTextFile(path));
    if (secret.empty()) throw std::runtime_error(path + " is empty: it should hold a token");
    struct stat st {};
    // Group access is how Kubernetes (fsGroup) and Compose hand secrets to a service's
    // user; access for every user is what gives a token away.
    if (::stat(path.c_str(), &st) == 0 && (st.st_mode & S_IRWXO) != 0)
        spdlog::warn("{} may be read by every user of this machine (chmod o-rwx it)", path);
    return secret;
}

ClientSecurity ClientSecurityFlags::Resolve() const {
    ClientSecurity s;
    s.ca_file = !ca_file.empty() ? ca_file : Env("TESSERA_TLS_CA");
    s.cert_file = !cert_file.empty() ? cert_file : Env("TESSERA_TLS_CERT");
    s.key_file = !key_file.empty() ? key_file : Env("TESSERA_TLS_KEY");
    s.server_name = !server_name.empty() ? server_name : Env("TESSERA_TLS_SERVER_NAME");
    if (s.cert_file.empty() != s.key_file.empty())
        throw std::runtime_error("a client certificate needs both --tls-cert and --tls-key");
    if (!s.cert_file.empty() && s.ca_file.empty())
        throw std::runtime_error("a client certificate is for TLS: give the CA with --tls-ca");
    if (!token_file.empty()) {
        s.token = ReadSecretFile(token_file);
    } else if (std::string env = Trim(Env("TESSERA_TOKEN")); !env.empty()) {
        s.token = env;
    } else if (std::string file = Env("TESSERA_TOKEN_FILE"); !file.empty()) {
        s.token = ReadSecretFile(file);
    }
    return s;
}

std::shared_ptr<grpc::Channel> MakeChannel(const std::string& address,
                                           const ClientSecurity& security,
                                           grpc::ChannelArguments args) {
    std::shared_ptr<grpc::ChannelCredentials> credentials;
    if (security.Tls()) {
        grpc::SslCredentialsOptions ssl;
        ssl.pem_root_certs = ReadTextFile(security.ca_file);
        if (!security.cert_file.empty()) {
            ssl.pem_cert_chain = ReadTextFile(security.cert_file);
            ssl.pem_private_key = ReadTextFile(security.key_file);
        }
        credentials = grpc::SslCredentials(ssl);
        if (!security.server_name.empty()) args.SetSslTargetNameOverride(security.server_name);
    } else {
        credentials = grpc::InsecureChannelCredentials();
    }
    if (security.token.empty()) return grpc::CreateCustomChannel(address, credentials, args);
    std::vector<std::unique_ptr<grpc::experimental::ClientInterceptorFactoryInterface>> factories;
    factories.push_back(std::make_unique<TokenInterceptorFactory>(security.token));
    return grpc::experimental::CreateCustomChannelWithInterceptors(address, credentials, args,
                                                                   std::move(factories));
}

}  // namespace tessera
