#pragma once

// Text made safe inside XML or HTML (KML exports, the mission report): valid UTF-8 only (invalid
// bytes become U+FFFD), no characters XML 1.0 forbids (other control characters are dropped),
// and & < > " ' escaped.

#include <string>
#include <string_view>

namespace saker {

// How the apostrophe is written: &apos; (XML) or &#39; (HTML 4, which Qt's rich text reads).
enum class MarkupQuote { kXml, kHtml };

std::string EscapeMarkup(std::string_view text, MarkupQuote quote);

}  // namespace saker
