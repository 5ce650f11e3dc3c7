// Light Field Distance (Chen et al. 2003) as run by the DIMR evaluation: the LFD v1.8 programs
// `3DAlignment` (descriptors) and `Distance` shipped in ashawkey/light-field-distance,
// re-implemented from ../shared/reference/dimr-metrics.md section 6 and appendix A:
// 10 dodecahedron camera sets x 10 orthographic views of 256x256, a Mesa-exact silhouette
// rasteriser, per view 35 ART ("Zernike") magnitudes, 10 contour Fourier coefficients,
// circularity and eccentricity, each quantised to a byte, and the integer L1 distance minimised
// over camera sets and the 60 dodecahedron rotations.
#pragma once

#include <array>
#include <cstdint>
#include <memory>
#include <mutex>
#include <string>
#include <unordered_map>
#include <vector>

#include "dimr/geometry/types.h"

namespace dimr::eval::lfd {

constexpr int kSets = 10;
constexpr int kViews = 10;
constexpr int kArt = 35;
constexpr int kFd = 10;
constexpr int kSize = 256;  // silhouette width = height

// Quantised descriptor of one mesh, [set][view][coefficient] order as in the reference files.
struct Descriptor {
  std::array<std::uint8_t, kSets * kViews * kArt> art{};
  std::array<std::uint8_t, kSets * kViews * kFd> fd{};
  std::array<std::uint8_t, kSets * kViews> cir{};
  std::array<std::uint8_t, kSets * kViews> ecc{};
  bool operator==(const Descriptor& o) const {
    return art == o.art && fd == o.fd && cir == o.cir && ecc == o.ecc;
  }
};

// Appendix A.1: eye positions, [set][view].
const std::array<std::array<geometry::Vec3, kViews>, kSets>& CameraSets();
// Appendix A.2: the 60 rotation permutations (columns 0-9 of align10.txt).
const std::array<std::array<std::uint8_t, kViews>, 60>& Align10();
// Appendix A.3: thinning deletion table (index = 8-neighbour code).
bool DelTab(int code);

// A silhouette: kSize*kSize bytes, 255 = background, 0 = foreground; row 0 is the bottom row
// (GL order), index = y * kSize + x.
using Image = std::vector<std::uint8_t>;

// The reference normalisation: centre the bbox of face-referenced vertices at the origin and
// scale by 1 / max extent (model inside [-1/2, 1/2]^3). Returns the normalised vertices.
std::vector<geometry::Vec3> NormalizeForLfd(const geometry::TriangleMesh& mesh);
// Orthographic silhouette seen from `eye` (looking at the origin, up = +y), rasterised with
// 1/256-pixel snapping and the top-left fill rule (section 6.2.5).
Image RenderSilhouette(const std::vector<geometry::Vec3>& vertices,
                       const std::vector<geometry::Vec3i>& faces, const geometry::Vec3& eye);

// Per-view pieces (exposed for tests).
struct ViewCentre {
  double cx = -1, cy = -1;
  int count = 0;                                 // |F|
  int minx = 0, maxx = -1, miny = 0, maxy = -1;  // foreground bbox (empty: max < min)
};
ViewCentre ComputeCentre(const Image& img);
// Quantised eccentricity and circularity bytes.
std::uint8_t EccentricityByte(const Image& img, const ViewCentre& c);
std::uint8_t CircularityByte(const Image& img);
// 35 ART bytes for scale r = 50 / R_k. Pixels are splatted onto the 101x101 LUT nodes with
// their bilinear weights, then projected on the basis once per node (the same sum regrouped,
// equal up to rounding; many times faster than the per-pixel loop).
void ArtBytes(const Image& img, const ViewCentre& c, double r, std::uint8_t* out35);
// The reference's loop order (per pixel, per coefficient bilinear lookup); for tests.
void ArtBytesDirect(const Image& img, const ViewCentre& c, double r, std::uint8_t* out35);
// Contour trace (section 6.3 FD step 1); returns the contour pixel indices including the start
// twice, or an empty vector for the reference's -1.
std::vector<int> TraceContour(const Image& img);
// 10 Fourier-descriptor bytes (handles multipart silhouettes by dilation + thinning).
void FourierBytes(const Image& img, const ViewCentre& c, std::uint8_t* out10);

// Full descriptor of a mesh (100 renders). Thread-safe, deterministic.
Descriptor ComputeDescriptor(const geometry::TriangleMesh& mesh);

// Distance(pred, gt) as printed by the reference `Distance pred gt` when `gt_ecc` is false (the
// GT eccentricity is never read and compares against 0, spec section 6.6). With `gt_ecc` true
// the GT eccentricity is used (the corrected, symmetric distance; 0 for identical shapes).
long long Distance(const Descriptor& pred, const Descriptor& gt, bool gt_ecc);

// 64-bit FNV-1a content hash of a mesh's vertex and face bytes (not its file name).
std::uint64_t MeshHash(const geometry::TriangleMesh& mesh);

// Descriptors cached by content hash in memory and optionally in `dir` (`<hash>.lfd` files).
class DescriptorCache {
 public:
  explicit DescriptorCache(std::string dir = "");
  std::shared_ptr<const Descriptor> Get(const geometry::TriangleMesh& mesh);
  std::size_t computed() const { return computed_; }
  std::size_t hits() const { return hits_; }

 private:
  std::string dir_;
  std::mutex mu_;
  std::unordered_map<std::uint64_t, std::shared_ptr<const Descriptor>> map_;
  std::size_t computed_ = 0;
  std::size_t hits_ = 0;
};

}  // namespace dimr::eval::lfd
