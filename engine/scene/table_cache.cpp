#include "scene/table_cache.h"

#include <fmt/format.h>

#include <stdexcept>

#include "core/wire_format.h"
#include "light/structured_sampling.h"
#include "material/factored_brdf.h"

namespace tessera {

std::string TableKey(std::string_view bytes, const std::string& how) {
    return fmt::format("{:016x}-{}-{}", wire::Fnv1a(bytes), bytes.size(), how);
}

FileTableCache<StructuredSampling>& StrataTables() {
    static FileTableCache<StructuredSampling> cache;
    return cache;
}

FileTableCache<FactoredBrdf>& FactoredTables() {
    static FileTableCache<FactoredBrdf> cache;
    return cache;
}

std::shared_ptr<const void> InstallTables(const std::vector<EncodedTable>& tables) {
    auto held = std::make_shared<std::vector<std::shared_ptr<const void>>>();
    for (const EncodedTable& t : tables) {
        try {
            if (t.kind == kStrataTableKind) {
                auto table =
                    std::make_shared<const StructuredSampling>(StructuredSampling::Decode(t.bytes));
                StrataTables().Put(t.key, table);
                held->push_back(table);
            } else if (t.kind == kFactoredTableKind) {
                auto table = std::make_shared<const FactoredBrdf>(FactoredBrdf::Decode(t.bytes));
                FactoredTables().Put(t.key, table);
                held->push_back(table);
            } else {
                throw std::runtime_error("unknown kind of table '" + t.kind + "'");
            }
        } catch (const std::exception& e) {
            throw std::runtime_error("precomputed table " + t.key + ": " + e.what());
        }
    }
    return held;
}

}  // namespace tessera
