#pragma once

// The dashboard's page, script and style sheet (coordinator/dashboard/), built into the
// coordinator by coordinator/embed_assets.cmake: nothing to install beside the binary.

#include <string_view>

namespace tessera {

struct DashboardAsset {
    std::string_view name;  // its file name in coordinator/dashboard: "app.js"
    std::string_view bytes;
};

// The asset of that file name, or null.
const DashboardAsset* FindDashboardAsset(std::string_view name);

}  // namespace tessera
