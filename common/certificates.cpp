#include "certificates.h"

#include <arpa/inet.h>
#include <openssl/bio.h>
#include <openssl/bn.h>
#include <openssl/evp.h>
#include <openssl/pem.h>
#include <openssl/rand.h>
#include <openssl/x509.h>
#include <openssl/x509v3.h>

#include <memory>
#include <stdexcept>

namespace tessera {
namespace {

template <typename T, void (*Free)(T*)>
struct Deleter {
    void operator()(T* p) const { Free(p); }
};
using Key = std::unique_ptr<EVP_PKEY, Deleter<EVP_PKEY, EVP_PKEY_free>>;
using Cert = std::unique_ptr<X509, Deleter<X509, X509_free>>;
using Bio = std::unique_ptr<BIO, Deleter<BIO, BIO_free_all>>;

void Check(bool ok, const char* what) {
    if (!ok) throw std::runtime_error(std::string("cannot create the certificate: ") + what);
}

Key NewKey() {
    Key key(EVP_EC_gen("P-256"));
    Check(key != nullptr, "key generation failed");
    return key;
}

std::string ToPem(const Key& key) {
    Bio bio(BIO_new(BIO_s_mem()));
    Check(
        PEM_write_bio_PrivateKey(bio.get(), key.get(), nullptr, nullptr, 0, nullptr, nullptr) == 1,
        "cannot encode the key");
    char* data = nullptr;
    const long size = BIO_get_mem_data(bio.get(), &data);
    return std::string(data, static_cast<size_t>(size));
}

std::string ToPem(const Cert& cert) {
    Bio bio(BIO_new(BIO_s_mem()));
    Check(PEM_write_bio_X509(bio.get(), cert.get()) == 1, "cannot encode the certificate");
    char* data = nullptr;
    const long size = BIO_get_mem_data(bio.get(), &data);
    return std::string(data, static_cast<size_t>(size));
}

void AddExtension(X509* cert, X509* issuer, int nid, const std::string& value) {
    X509V3_CTX ctx;
    X509V3_set_ctx_nodb(&ctx);
    X509V3_set_ctx(&ctx, issuer, cert, nullptr, nullptr, 0);
    X509_EXTENSION* ext = X509V3_EXT_conf_nid(nullptr, &ctx, nid, value.c_str());
    Check(ext != nullptr, value.c_str());
    const int added = X509_add_ext(cert, ext, -1);
    X509_EXTENSION_free(ext);
    Check(added == 1, value.c_str());
}

// Version 3, a random 128-bit serial, valid from an hour ago (clock skew) for `days`.
Cert NewCertificate(const Key& key, const std::string& common_name, int days) {
    if (common_name.empty()) throw std::runtime_error("a certificate needs a name");
    if (days < 1) throw std::runtime_error("a certificate must be valid for a day at least");
    Cert cert(X509_new());
    Check(cert != nullptr, "out of memory");
    X509_set_version(cert.get(), 2);
    unsigned char serial[16];
    Check(RAND_bytes(serial, sizeof serial) == 1, "no random numbers");
    serial[0] &= 0x7f;  // positive
    BIGNUM* bn = BN_bin2bn(serial, sizeof serial, nullptr);
    Check(bn && BN_to_ASN1_INTEGER(bn, X509_get_serialNumber(cert.get())), "bad serial");
    BN_free(bn);
    X509_gmtime_adj(X509_getm_notBefore(cert.get()), -3600);
    X509_gmtime_adj(X509_getm_notAfter(cert.get()), int64_t(days) * 86400);
    Check(X509_set_pubkey(cert.get(), key.get()) == 1, "bad key");
    X509_NAME* name = X509_get_subject_name(cert.get());
    Check(X509_NAME_add_entry_by_txt(name, "CN", MBSTRING_UTF8,
                                     reinterpret_cast<const unsigned char*>(common_name.c_str()),
                                     -1, -1, 0) == 1,
          "bad common name");
    return cert;
}

std::string AltName(const std::string& name) {
    if (name.empty()) throw std::runtime_error("an empty name for a certificate");
    unsigned char addr[16];
    if (inet_pton(AF_INET, name.c_str(), addr) == 1 || inet_pton(AF_INET6, name.c_str(), addr) == 1)
        return "IP:" + name;
    for (char c : name)
        if (c == ',' || c == ':' || c == ' ')
            throw std::runtime_error("'" + name + "' is neither a host name nor an IP address");
    return "DNS:" + name;
}

}  // namespace

KeyAndCertificate MakeCertificateAuthority(const std::string& common_name, int days) {
    Key key = NewKey();
    Cert cert = NewCertificate(key, common_name, days);
    Check(X509_set_issuer_name(cert.get(), X509_get_subject_name(cert.get())) == 1, "issuer");
    AddExtension(cert.get(), cert.get(), NID_basic_constraints, "critical,CA:TRUE,pathlen:0");
    AddExtension(cert.get(), cert.get(), NID_key_usage, "critical,keyCertSign,cRLSign");
    AddExtension(cert.get(), cert.get(), NID_subject_key_identifier, "hash");
    Check(X509_sign(cert.get(), key.get(), EVP_sha256()) > 0, "signing failed");
    return {ToPem(key), ToPem(cert)};
}

KeyAndCertificate MakeCertificate(const KeyAndCertificate& ca, const std::string& common_name,
                                  const std::vector<std::string>& names, int days) {
    Bio key_bio(BIO_new_mem_buf(ca.key_pem.data(), static_cast<int>(ca.key_pem.size())));
    Key ca_key(PEM_read_bio_PrivateKey(key_bio.get(), nullptr, nullptr, nullptr));
    if (!ca_key) throw std::runtime_error("the CA key does not parse (PEM expected)");
    Bio cert_bio(
        BIO_new_mem_buf(ca.certificate_pem.data(), static_cast<int>(ca.certificate_pem.size())));
    Cert ca_cert(PEM_read_bio_X509(cert_bio.get(), nullptr, nullptr, nullptr));
    if (!ca_cert) throw std::runtime_error("the CA certificate does not parse (PEM expected)");
    if (X509_check_private_key(ca_cert.get(), ca_key.get()) != 1)
        throw std::runtime_error("the CA key does not belong to the CA certificate");

    Key key = NewKey();
    Cert cert = NewCertificate(key, common_name, days);
    Check(X509_set_issuer_name(cert.get(), X509_get_subject_name(ca_cert.get())) == 1, "issuer");
    AddExtension(cert.get(), ca_cert.get(), NID_basic_constraints, "critical,CA:FALSE");
    AddExtension(cert.get(), ca_cert.get(), NID_key_usage, "critical,digitalSignature");
    AddExtension(cert.get(), ca_cert.get(), NID_ext_key_usage, "serverAuth,clientAuth");
    AddExtension(cert.get(), ca_cert.get(), NID_subject_key_identifier, "hash");
    AddExtension(cert.get(), ca_cert.get(), NID_authority_key_identifier, "keyid");
    std::string alt;
    for (const std::string& name : names) alt += (alt.empty() ? "" : ",") + AltName(name);
    if (!alt.empty()) AddExtension(cert.get(), ca_cert.get(), NID_subject_alt_name, alt);
    Check(X509_sign(cert.get(), ca_key.get(), EVP_sha256()) > 0, "signing failed");
    return {ToPem(key), ToPem(cert)};
}

std::string NewToken() {
    unsigned char bytes[32];
    if (RAND_bytes(bytes, sizeof bytes) != 1) throw std::runtime_error("no random numbers");
    static const char* kHex = "0123456789abcdef";
    std::string token;
    for (unsigned char b : bytes) {
        token += kHex[b >> 4];
        token += kHex[b & 15];
    }
    return token;
}

}  // namespace tessera
