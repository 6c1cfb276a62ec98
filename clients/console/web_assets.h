// The web app's files (clients/console/web, bundled by esbuild at build
// time), compiled into the console so that it serves them from memory: one
// binary, nothing fetched from elsewhere.
#ifndef BITEWISE_CLIENTS_CONSOLE_WEB_ASSETS_H_
#define BITEWISE_CLIENTS_CONSOLE_WEB_ASSETS_H_

#include <cstddef>

namespace bitewise::console {

struct WebAsset {
  const char* path;  // "/app.js"
  const char* content_type;
  const unsigned char* data;
  size_t size;
};

// Null for an unknown path; "/" is "/index.html".
const WebAsset* FindWebAsset(const char* path);

// Every asset, for tests and the size benchmark.
const WebAsset* WebAssets(size_t* count);

}  // namespace bitewise::console

#endif  // BITEWISE_CLIENTS_CONSOLE_WEB_ASSETS_H_
