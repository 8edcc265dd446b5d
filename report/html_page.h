// Building blocks of the self-contained HTML reports (`echoservo lab report`,
// lab/lab_report.h; `echoservo report`, report/accuracy_report.h).
//
// One page: inline CSS (PageCss, which includes the charts' rules from
// report/svg_plot.h), no external URL, font or script. The helpers return HTML
// fragments; text arguments named `*_html` or `cells` are already HTML, everything else is
// escaped by the caller with svg::EscapeHtml. Numbers are formatted locale-independently;
// non-finite values print as an en dash.
#pragma once

#include <cstddef>
#include <string>
#include <utility>
#include <vector>

namespace echoservo::report::html {

// "%.*f" and "%.*g"; "&ndash;" when `v` is not finite.
std::string Fix(double v, int decimals);
std::string Sig(double v, int digits);

// One table row; cells are HTML. The first `left` cells are left-aligned (text), the
// others right-aligned (numbers). `header`: <th> cells.
std::string Row(const std::vector<std::string>& cells, const std::string& row_class = "",
                bool header = false, std::size_t left = 1);

// A small yes/no badge.
std::string Tag(bool yes, const std::string& yes_text = "yes", const std::string& no_text = "no");

// The current date and time, "YYYY-MM-DD HH:MM UTC".
std::string NowUtc();

// The page's style sheet: layout, header, sections, tables, badges, verdict boxes, and the
// chart rules.
std::string PageCss();

// "<!DOCTYPE html>…<title>`title_html`</title><style>…</style></head><body><main>\n".
std::string PageStart(const std::string& title_html);

// The dark page header: a title, a subtitle line and a grid of facts (name, value; both
// HTML).
std::string TopHeader(const std::string& title_html, const std::string& subtitle_html,
                      const std::vector<std::pair<std::string, std::string>>& facts);

}  // namespace echoservo::report::html
