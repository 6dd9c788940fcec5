#pragma once
// The guarded opening of an image file for OpenImageIO, shared by core's readers
// (core/image.cpp) and the capture's (capture/capture.cpp), so every image a user hands
// Specula passes the same checks before a decoder sees it.
#include "core/image.h"

#include <OpenImageIO/imageio.h>

#include <filesystem>
#include <memory>
#include <string>

namespace specula {

/// Opens `path` for reading, colour with unassociated alpha (OIIO would otherwise premultiply
/// PNG colour by alpha). Checked first: the file exists and is a regular file (a FIFO would
/// block); an OpenEXR file's header is walked, and every attribute must fit in the bytes the
/// file holds and its data window within `max_dimension`, since OpenEXR allocates what the
/// header claims before reading it; a PNG file's chunks must fit in it likewise. Throws
/// InputError(path, field, ...).
[[nodiscard]] std::unique_ptr<OIIO::ImageInput> open_image_file(const std::filesystem::path& path,
                                                                 const std::string& field,
                                                                 int max_dimension = kMaxDecodedImageDimension);

} // namespace specula
