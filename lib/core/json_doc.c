/* One rule for every JSON document the library reads (cameras, registration parameters): the
 * document is exactly one value; anything but white space after it is an error. */
#include <cjson/cJSON.h>

#include "core/internal.h"

spx_status spx_json_parse_doc(spx_ctx *ctx, const char *name, const char *text, size_t len, struct cJSON **out) {
  *out = NULL;
  const char *end = NULL;
  cJSON *root = cJSON_ParseWithLengthOpts(text ? text : "", text ? len : 0, &end, 0);
  if (!root) {
    const char *at = cJSON_GetErrorPtr();
    long off = at && text && at >= text && at <= text + len ? (long)(at - text) : -1;
    return spx_fail(ctx, SPX_E_FORMAT, "%s: invalid JSON (near byte %ld)", name, off);
  }
  for (const char *p = end; p && p < text + len; p++)
    if (*p != ' ' && *p != '\t' && *p != '\n' && *p != '\r') {
      cJSON_Delete(root);
      return spx_fail(ctx, SPX_E_FORMAT, "%s: unexpected text after the JSON value (byte %ld)", name, (long)(p - text));
    }
  *out = root;
  return SPX_OK;
}
