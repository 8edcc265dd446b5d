#include "report/html_page.h"

#include <cmath>
#include <cstdio>
#include <ctime>

#include "report/svg_plot.h"

namespace echoservo::report::html {

std::string Fix(double v, int decimals) {
  if (!std::isfinite(v)) return "&ndash;";
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.*f", decimals, v);
  return buf;
}

std::string Sig(double v, int digits) {
  if (!std::isfinite(v)) return "&ndash;";
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.*g", digits, v);
  return buf;
}

std::string Row(const std::vector<std::string>& cells, const std::string& row_class, bool header,
                std::size_t left) {
  std::string s = row_class.empty() ? "<tr>" : "<tr class=\"" + row_class + "\">";
  const std::string tag = header ? "th" : "td";
  for (std::size_t i = 0; i < cells.size(); ++i) {
    s += "<" + tag + (i < left ? " class=\"l\">" : ">") + cells[i] + "</" + tag + ">";
  }
  return s + "</tr>";
}

std::string Tag(bool yes, const std::string& yes_text, const std::string& no_text) {
  return yes ? "<span class=\"tag yes\">" + yes_text + "</span>"
             : "<span class=\"tag no\">" + no_text + "</span>";
}

std::string NowUtc() {
  const std::time_t now = std::time(nullptr);
  std::tm tm{};
  gmtime_r(&now, &tm);
  char buf[64];
  std::strftime(buf, sizeof buf, "%Y-%m-%d %H:%M UTC", &tm);
  return buf;
}

std::string PageCss() {
  return std::string(
             "*{box-sizing:border-box}"
             "body{margin:0;background:#f4f5f7;color:#1d1d1f;font:14px/1.45 "
             "system-ui,-apple-system,'Segoe UI',"
             "Roboto,'Helvetica Neue',Arial,sans-serif}"
             "main{max-width:1220px;margin:0 auto;padding:20px 24px 40px}"
             "header.top{background:#1f2d3d;color:#fff;border-radius:8px;padding:18px "
             "22px;margin-bottom:18px}"
             "header.top h1{margin:0 0 4px;font-size:22px;font-weight:600}"
             "header.top .sub{color:#c8d3df;margin:0 0 12px}"
             "dl.facts{display:grid;grid-template-columns:repeat(auto-fill,minmax(260px,1fr));gap:"
             "8px 22px;margin:0}"
             "dl.facts div{min-width:0}"
             "dl.facts dt{font-size:12px;letter-spacing:.02em;color:#9fb3c8}"
             "dl.facts dd{margin:0;font-weight:500;overflow-wrap:anywhere}"
             "nav.toc{margin:0 0 16px;font-size:13px}"
             "nav.toc a{margin-right:14px;color:#0b5cad;text-decoration:none}"
             "section{background:#fff;border:1px solid #dfe3e8;border-radius:8px;padding:16px "
             "20px;margin-bottom:18px}"
             "h2{font-size:18px;margin:0 0 10px;font-weight:600}"
             "h3{font-size:15px;margin:18px 0 6px;font-weight:600;overflow-wrap:anywhere}"
             "p.note{color:#555;margin:4px 0 12px;font-size:13px}"
             "table{border-collapse:collapse;font-size:13px;margin:6px 0 12px}"
             "th,td{padding:4px 10px;border-bottom:1px solid "
             "#e6e9ed;text-align:right;white-space:nowrap}"
             "th{background:#f0f2f5;font-weight:600;color:#333}"
             "td.l,th.l{text-align:left}"
             "tr.sig td{background:#fff4e5}"
             "tr.final td{font-weight:600}"
             "td.name{white-space:normal;overflow-wrap:break-word;min-width:220px}"
             ".scroll{max-height:420px;overflow-y:auto;overflow-x:auto;border:1px solid "
             "#eceff2;border-radius:4px}"
             ".scroll table{margin:0;width:100%}"
             ".scroll th{position:sticky;top:0}"
             ".grid2{display:grid;grid-template-columns:repeat(auto-fit,minmax(520px,1fr));gap:"
             "12px 18px;"
             "align-items:start}"
             ".grid2>div{min-width:0}"
             ".verdict{border-radius:6px;padding:10px 14px;margin:8px 0 12px;font-size:14px}"
             ".verdict b{margin-right:6px}"
             ".verdict.ok{background:#e8f5e9;border-left:5px solid #2e7d32}"
             ".verdict.miss{background:#fff3e0;border-left:5px solid #e66101}"
             "ol.evidence{padding-left:22px;margin:6px 0}"
             "ol.evidence li{margin:4px 0;color:#333}"
             ".tag{display:inline-block;font-size:11px;padding:1px "
             "7px;border-radius:10px;font-weight:600}"
             ".tag.yes{background:#e8f5e9;color:#1b5e20}.tag.no{background:#eceff1;color:#546e7a}"
             ".tag.miss{background:#fff3e0;color:#a84300}"
             ".trial-panel{border-top:1px solid #e6e9ed;margin-top:14px;padding-top:4px}"
             ".trial-panel .cfg{color:#555;font-size:13px;margin:0 0 8px}"
             ".selector{margin:8px 0 4px;font-size:13px}"
             ".selector select{font:inherit;padding:3px 6px;margin-left:6px;max-width:100%}"
             "code{font-family:ui-monospace,Menlo,Consolas,monospace;font-size:12.5px;background:#"
             "f0f2f5;"
             "padding:1px 4px;border-radius:3px;overflow-wrap:anywhere}"
             "header.top code{background:#2c3e50;color:#fff}"
             "details{margin:6px 0 0}summary{cursor:pointer;color:#0b5cad;font-size:13px}"
             "footer{color:#777;font-size:12px;text-align:center;margin-top:10px}"
             "[hidden]{display:none!important}") +
         std::string(svg::ChartCss());
}

std::string PageStart(const std::string& title_html) {
  return "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">"
         "<meta name=\"viewport\" content=\"width=device-width, initial-scale=1\">"
         "<link rel=\"icon\" href=\"data:,\"><title>" +
         title_html + "</title><style>" + PageCss() + "</style></head><body><main>\n";
}

std::string TopHeader(const std::string& title_html, const std::string& subtitle_html,
                      const std::vector<std::pair<std::string, std::string>>& facts) {
  std::string s = "<header class=\"top\"><h1>" + title_html + "</h1><p class=\"sub\">" +
                  subtitle_html + "</p><dl class=\"facts\">";
  for (const auto& [k, v] : facts) s += "<div><dt>" + k + "</dt><dd>" + v + "</dd></div>";
  return s + "</dl></header>";
}

}  // namespace echoservo::report::html
