#include "products/report_page.h"

#include <gtest/gtest.h>

namespace skyfall {
namespace {

TEST(ReportPage, UrlPathEncodesWhatWouldBreakALink) {
  EXPECT_EQ(UrlPath("JAX_068/tiles/JAX_068_c0_r0/splat/heldout/JAX_068_002_RGB_render.png"),
            "JAX_068/tiles/JAX_068_c0_r0/splat/heldout/JAX_068_002_RGB_render.png");
  EXPECT_EQ(UrlPath("my scene/view #1 100%.png"), "my%20scene/view%20%231%20100%25.png");
  EXPECT_EQ(UrlPath("a?b&c\"d"), "a%3Fb%26c%22d");
  EXPECT_EQ(UrlPath("caf\xC3\xA9"), "caf%C3%A9");  // UTF-8 bytes, each encoded
  EXPECT_EQ(UrlPath("../x~y-z.w_"), "../x~y-z.w_");
}

TEST(ReportPage, HtmlEscapeAndBase64) {
  EXPECT_EQ(HtmlEscape("<a href=\"x\">&'</a>"), "&lt;a href=&quot;x&quot;&gt;&amp;&#39;&lt;/a&gt;");
  EXPECT_EQ(Base64(""), "");
  EXPECT_EQ(Base64("f"), "Zg==");
  EXPECT_EQ(Base64("fo"), "Zm8=");
  EXPECT_EQ(Base64("foo"), "Zm9v");
  EXPECT_EQ(Base64("foobar"), "Zm9vYmFy");  // RFC 4648's test vectors
}

}  // namespace
}  // namespace skyfall
