#pragma once
// The dashboard's page, script, style sheet and icon (master/web/), embedded in the binary at
// build time (cmake/embed_web.cmake), so that the master serves them without files beside it and
// the page fetches nothing from elsewhere.
#include <string_view>

namespace rayfarm::master::web {

extern const std::string_view kIndexHtml;
extern const std::string_view kDashboardJs;
extern const std::string_view kDashboardCss;
extern const std::string_view kFaviconSvg;

}  // namespace rayfarm::master::web
