/* One rule for every JSON document the library reads (cameras, registration parameters, poses,
 * safetensors headers): the document is exactly one value, anything but white space after it is
 * an error, and no object names a key twice (which one would count is not said anywhere). */
#include <cjson/cJSON.h>

#include <stdlib.h>
#include <string.h>

#include "core/internal.h"

static int cmp_key(const void *a, const void *b) { return strcmp(*(const char *const *)a, *(const char *const *)b); }

/* A key the object's members name twice: pairwise for a few members, sorted for many (a hostile
 * document of a million keys stays n log n). */
static const char *object_duplicate(const cJSON *obj) {
  size_t n = 0;
  for (const cJSON *a = obj->child; a; a = a->next) n += a->string != NULL;
  const char **keys = n > 32 ? malloc(n * sizeof *keys) : NULL;
  if (!keys) { /* few members (or no memory for the sort) */
    for (const cJSON *a = obj->child; a; a = a->next)
      for (const cJSON *b = a->next; b; b = b->next)
        if (a->string && b->string && !strcmp(a->string, b->string)) return a->string;
    return NULL;
  }
  size_t k = 0;
  for (const cJSON *a = obj->child; a; a = a->next)
    if (a->string) keys[k++] = a->string;
  qsort(keys, k, sizeof *keys, cmp_key);
  const char *dup = NULL;
  for (size_t i = 1; i < k && !dup; i++)
    if (!strcmp(keys[i - 1], keys[i])) dup = keys[i];
  free(keys);
  return dup;
}

const char *spx_json_duplicate_key(const struct cJSON *node) {
  for (; node; node = node->next) {
    const char *d = cJSON_IsObject(node) ? object_duplicate(node) : NULL;
    if (!d && node->child) d = spx_json_duplicate_key(node->child);
    if (d) return d;
  }
  return NULL;
}

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
  const char *dup = spx_json_duplicate_key(root);
  if (dup) {
    spx_status st = spx_fail(ctx, SPX_E_FORMAT, "%s: key \"%.60s\" appears twice in one object", name, dup);
    cJSON_Delete(root);
    return st;
  }
  *out = root;
  return SPX_OK;
}
