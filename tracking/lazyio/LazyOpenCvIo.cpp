// OpenCV's image-file and video modules (imgcodecs, videoio), loaded on first use
// instead of at the start of the `mmval` executable.
//
// Why: linked as usual, the two modules bring 180 of the executable's 329 shared
// libraries (GDAL, FFmpeg, GStreamer and theirs); the dynamic loader's symbol lookups for
// them cost ~0.1 s of every start (measured: 0.21 s for `mmval --version` against 0.10-0.12 s
// without them), though `mmval track` on a PNG folder never calls them (its frames and
// pictures go through libdeflate: PngReader.hpp, PngWriter.hpp). The executable calls
// 18 functions of theirs; this file defines each of those symbols, and the first call
// opens the module with dlopen and forwards to its own definition (found with dlsym).
// Linked into `mmval` only, with --as-needed, so the modules are no longer among its
// needed libraries; the tests and benches link OpenCV as usual.
//
// The symbols are the Itanium C++ ABI names of OpenCV 4's declarations (GCC and Clang,
// libstdc++'s C++11 std::string) and each forwarder passes its arguments as that ABI
// does: `this` first for members, a class returned by value (cv::Mat) through the
// caller's return slot, given first; cv::Size by value in one register (two ints,
// trivially copyable). No OpenCV header is included: defining cv::VideoCapture's
// members in C++ would also emit its virtual table here. If a new OpenCV function from
// these modules is called anywhere in the executable, the linker resolves it from the
// module itself, which is then needed at start again (slower, still correct).
#include <dlfcn.h>

#include <cstddef>
#include <stdexcept>
#include <string>

#ifndef MMVAL_OPENCV_IMGCODECS
#error "MMVAL_OPENCV_IMGCODECS (the imgcodecs module's file name) must be defined"
#endif
#ifndef MMVAL_OPENCV_VIDEOIO
#error "MMVAL_OPENCV_VIDEOIO (the videoio module's file name) must be defined"
#endif

namespace {

/// The module, opened once (thread-safe); throws when it cannot be opened.
void* openModule(const char* file) {
  void* handle = dlopen(file, RTLD_LAZY | RTLD_LOCAL);
  if (handle == nullptr) {
    const char* why = dlerror();
    throw std::runtime_error(std::string("cannot load OpenCV's module ") + file + ": " + (why != nullptr ? why : "unknown error"));
  }
  return handle;
}

void* imgcodecs() {
  static void* const handle = openModule(MMVAL_OPENCV_IMGCODECS);
  return handle;
}

void* videoio() {
  static void* const handle = openModule(MMVAL_OPENCV_VIDEOIO);
  return handle;
}

/// The module's own definition of `symbol`.
template <class Function>
Function definition(void* module, const char* symbol) {
  void* address = dlsym(module, symbol);
  if (address == nullptr) throw std::runtime_error(std::string("OpenCV's module lacks ") + symbol);
  return reinterpret_cast<Function>(address);
}

}  // namespace

// Each forwarder: `static const auto real = definition<...>(module(), "its own name")`
// resolves once (thread-safe), then calls with the same arguments.
#define MMVAL_FORWARD(module, name, Ret, Params, Args)                   \
  extern "C" Ret name Params {                                           \
    static const auto real = definition<Ret(*) Params>(module(), #name); \
    return real Args;                                                    \
  }

// NOLINTBEGIN(bugprone-reserved-identifier): the names are the C++ symbols being defined.
// imgcodecs
// cv::Mat cv::imread(const std::string& filename, int flags): the Mat is built in `result`.
MMVAL_FORWARD(imgcodecs, _ZN2cv6imreadERKNSt7__cxx1112basic_stringIcSt11char_traitsIcESaIcEEEi, void*,
              (void* result, const void* filename, int flags), (result, filename, flags))
// bool cv::imreadmulti(const std::string&, std::vector<cv::Mat>&, int start, int count, int flags)
MMVAL_FORWARD(imgcodecs, _ZN2cv11imreadmultiERKNSt7__cxx1112basic_stringIcSt11char_traitsIcESaIcEEERSt6vectorINS_3MatESaIS9_EEiii, bool,
              (const void* filename, void* mats, int start, int count, int flags), (filename, mats, start, count, flags))
// std::size_t cv::imcount(const std::string&, int flags)
MMVAL_FORWARD(imgcodecs, _ZN2cv7imcountERKNSt7__cxx1112basic_stringIcSt11char_traitsIcESaIcEEEi, std::size_t, (const void* filename, int flags),
              (filename, flags))
// bool cv::imwrite(const std::string&, cv::InputArray, const std::vector<int>& params)
MMVAL_FORWARD(imgcodecs, _ZN2cv7imwriteERKNSt7__cxx1112basic_stringIcSt11char_traitsIcESaIcEEERKNS_11_InputArrayERKSt6vectorIiSaIiEE, bool,
              (const void* filename, const void* image, const void* params), (filename, image, params))
// bool cv::imencode(const std::string& ext, cv::InputArray, std::vector<uchar>& buf, const std::vector<int>& params)
MMVAL_FORWARD(imgcodecs, _ZN2cv8imencodeERKNSt7__cxx1112basic_stringIcSt11char_traitsIcESaIcEEERKNS_11_InputArrayERSt6vectorIhSaIhEERKSB_IiSaIiEE, bool,
              (const void* ext, const void* image, void* buf, const void* params), (ext, image, buf, params))

// videoio: cv::VideoWriter
namespace mmval::lazyio {
struct SizeInt {  // cv::Size_<int>, passed by value as OpenCV declares it
  int width, height;
};
}  // namespace mmval::lazyio
// bool cv::VideoWriter::open(const std::string&, int api, int fourcc, double fps, cv::Size, bool is_color)
MMVAL_FORWARD(videoio, _ZN2cv11VideoWriter4openERKNSt7__cxx1112basic_stringIcSt11char_traitsIcESaIcEEEiidNS_5Size_IiEEb, bool,
              (void* self, const void* filename, int api, int fourcc, double fps, mmval::lazyio::SizeInt size, bool is_color),
              (self, filename, api, fourcc, fps, size, is_color))
MMVAL_FORWARD(videoio, _ZN2cv11VideoWriter5writeERKNS_11_InputArrayE, void, (void* self, const void* image), (self, image))
MMVAL_FORWARD(videoio, _ZN2cv11VideoWriter6fourccEcccc, int, (char c1, char c2, char c3, char c4), (c1, c2, c3, c4))
MMVAL_FORWARD(videoio, _ZN2cv11VideoWriter7releaseEv, void, (void* self), (self))
MMVAL_FORWARD(videoio, _ZN2cv11VideoWriterC1Ev, void, (void* self), (self))
MMVAL_FORWARD(videoio, _ZN2cv11VideoWriterD1Ev, void, (void* self), (self))

// videoio: cv::VideoCapture
MMVAL_FORWARD(videoio, _ZN2cv12VideoCapture3setEid, bool, (void* self, int property, double value), (self, property, value))
MMVAL_FORWARD(videoio, _ZN2cv12VideoCapture4grabEv, bool, (void* self), (self))
MMVAL_FORWARD(videoio, _ZN2cv12VideoCapture4openERKNSt7__cxx1112basic_stringIcSt11char_traitsIcESaIcEEEi, bool,
              (void* self, const void* filename, int api), (self, filename, api))
MMVAL_FORWARD(videoio, _ZN2cv12VideoCapture4readERKNS_12_OutputArrayE, bool, (void* self, const void* image), (self, image))
MMVAL_FORWARD(videoio, _ZN2cv12VideoCaptureC1Ev, void, (void* self), (self))
MMVAL_FORWARD(videoio, _ZN2cv12VideoCaptureD1Ev, void, (void* self), (self))
MMVAL_FORWARD(videoio, _ZNK2cv12VideoCapture3getEi, double, (const void* self, int property), (self, property))
// NOLINTEND(bugprone-reserved-identifier)
