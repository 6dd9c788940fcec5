// Reference for image_metrics: every sum in double, the SSIM and Hausdorff math from
// metrics/image_metrics_shared.h instantiated in double (shared::f64). The definitions
// are in image_metrics.h.
#include "metrics/image_metrics.h"

#include "metrics/image_metrics_shared.h"

#include <algorithm>
#include <cmath>
#include <vector>

namespace specula::metrics {

namespace {

namespace f64 = shared::f64;

struct View {
    const Image& a;
    const Image& b;
    std::span<const uint8_t> mask;
    int w, h, ch, cc;
    [[nodiscard]] bool in_set(int x, int y) const {
        return mask.empty() || mask[static_cast<std::size_t>(y) * static_cast<std::size_t>(w) + static_cast<std::size_t>(x)] != 0;
    }
};

void accumulate_sums(const View& v, MetricsSums& s) {
    for (int y = 0; y < v.h; ++y)
        for (int x = 0; x < v.w; ++x) {
            if (!v.in_set(x, y)) continue;
            ++s.count;
            double sq = 0.0;
            for (int c = 0; c < v.cc; ++c) {
                const double a = v.a.at(x, y, c);
                const double b = v.b.at(x, y, c);
                const double d = a - b;
                sq += d * d;
                s.sum_abs += std::abs(d);
                s.sum_ab += a * b;
                s.sum_aa += a * a;
                s.sum_bb += b * b;
            }
            s.sum_sq += sq;
            s.sum_l2 += std::sqrt(sq);
        }
}

std::vector<double> luma(const Image& img, int cc) {
    std::vector<double> out(static_cast<std::size_t>(img.width) * static_cast<std::size_t>(img.height));
    for (int y = 0; y < img.height; ++y)
        for (int x = 0; x < img.width; ++x) {
            const double r = img.at(x, y, 0);
            const double g = cc == 1 ? 0.0 : img.at(x, y, 1);
            const double b = cc == 1 ? 0.0 : img.at(x, y, 2);
            out[static_cast<std::size_t>(y) * static_cast<std::size_t>(img.width) + static_cast<std::size_t>(x)] =
                f64::metrics_luma(r, g, b, static_cast<uint32_t>(cc));
        }
    return out;
}

// SSIM map summed over P: separable Gaussian moments, truncated and renormalised at the border.
double ssim_sum(const View& v, const MetricsOptions& o) {
    const std::size_t w = static_cast<std::size_t>(v.w);
    const std::size_t n = w * static_cast<std::size_t>(v.h);
    const std::vector<double> ya = luma(v.a, v.cc);
    const std::vector<double> yb = luma(v.b, v.cc);
    double tap[2 * shared::kSsimRadius + 1];
    for (int d = -shared::kSsimRadius; d <= shared::kSsimRadius; ++d) tap[d + shared::kSsimRadius] = f64::ssim_gauss_tap(d);

    struct M { double mu_a, mu_b, aa, bb, ab; };
    std::vector<M> hm(n);
    for (int y = 0; y < v.h; ++y)
        for (int x = 0; x < v.w; ++x) {
            M m{0, 0, 0, 0, 0};
            double wsum = 0.0;
            for (int d = -shared::kSsimRadius; d <= shared::kSsimRadius; ++d) {
                const int xx = x + d;
                if (xx < 0 || xx >= v.w) continue;
                const double t = tap[d + shared::kSsimRadius];
                const std::size_t i = static_cast<std::size_t>(y) * w + static_cast<std::size_t>(xx);
                wsum += t;
                m.mu_a += t * ya[i];
                m.mu_b += t * yb[i];
                m.aa += t * ya[i] * ya[i];
                m.bb += t * yb[i] * yb[i];
                m.ab += t * ya[i] * yb[i];
            }
            hm[static_cast<std::size_t>(y) * w + static_cast<std::size_t>(x)] =
                M{m.mu_a / wsum, m.mu_b / wsum, m.aa / wsum, m.bb / wsum, m.ab / wsum};
        }
    const double c1 = (shared::kSsimK1 * o.peak) * (shared::kSsimK1 * o.peak);
    const double c2 = (shared::kSsimK2 * o.peak) * (shared::kSsimK2 * o.peak);
    double sum = 0.0;
    for (int y = 0; y < v.h; ++y)
        for (int x = 0; x < v.w; ++x) {
            if (!v.in_set(x, y)) continue;
            M m{0, 0, 0, 0, 0};
            double wsum = 0.0;
            for (int d = -shared::kSsimRadius; d <= shared::kSsimRadius; ++d) {
                const int yy = y + d;
                if (yy < 0 || yy >= v.h) continue;
                const double t = tap[d + shared::kSsimRadius];
                const M& q = hm[static_cast<std::size_t>(yy) * w + static_cast<std::size_t>(x)];
                wsum += t;
                m.mu_a += t * q.mu_a;
                m.mu_b += t * q.mu_b;
                m.aa += t * q.aa;
                m.bb += t * q.bb;
                m.ab += t * q.ab;
            }
            sum += f64::ssim_index(m.mu_a / wsum, m.mu_b / wsum, m.aa / wsum, m.bb / wsum, m.ab / wsum, c1, c2);
        }
    return sum;
}

// Directed Hausdorff h(X, Y) squared, over P (image_metrics.h): ring search per pixel.
double directed_hausdorff_d2(const Image& x_img, const Image& y_img, const View& v, const MetricsOptions& o,
                             bool& capped) {
    const double delta = o.hausdorff_delta;
    const int rmax = o.hausdorff_max_radius;
    double worst = 0.0;
    const auto color_d2 = [&](int px, int py, int qx, int qy) {
        double s = 0.0;
        for (int c = 0; c < v.cc; ++c) {
            const double d = static_cast<double>(x_img.at(px, py, c)) - static_cast<double>(y_img.at(qx, qy, c));
            s += d * d;
        }
        return s;
    };
    for (int py = 0; py < v.h; ++py)
        for (int px = 0; px < v.w; ++px) {
            if (!v.in_set(px, py)) continue;
            double best = color_d2(px, py, px, py); // q = p is in P
            const auto visit = [&](int qx, int qy) {
                if (qx < 0 || qy < 0 || qx >= v.w || qy >= v.h || !v.in_set(qx, qy)) return;
                best = std::min(best, f64::hausdorff_d2(qx - px, qy - py, delta, color_d2(px, py, qx, qy)));
            };
            int k = 1;
            for (; k <= rmax; ++k) {
                // Every q on Chebyshev ring k is at least k pixels from p.
                if (f64::hausdorff_d2(k, 0, delta, 0.0) >= best) break;
                for (int dx = -k; dx <= k; ++dx) {
                    visit(px + dx, py - k);
                    visit(px + dx, py + k);
                }
                for (int dy = -k + 1; dy <= k - 1; ++dy) {
                    visit(px - k, py + dy);
                    visit(px + k, py + dy);
                }
            }
            if (k > rmax && f64::hausdorff_d2(rmax + 1, 0, delta, 0.0) < best) capped = true;
            worst = std::max(worst, best);
        }
    return worst;
}

} // namespace

FrameMetrics image_metrics_cpu(const MetricsInputs& in, const MetricsOptions& options) {
    validate_metrics_inputs(in, options);
    const int cc = metrics_color_channels(in.captured.channels);
    const View v{in.captured, in.rendered, in.mask, in.captured.width, in.captured.height, in.captured.channels, cc};
    MetricsSums s;
    accumulate_sums(v, s);
    if (s.count > 0) {
        if (options.ssim) s.sum_ssim = ssim_sum(v, options);
        if (options.hausdorff) {
            bool capped = false;
            const double ab = directed_hausdorff_d2(in.captured, in.rendered, v, options, capped);
            const double ba = directed_hausdorff_d2(in.rendered, in.captured, v, options, capped);
            s.hausdorff_d2 = std::max(ab, ba); // eq. 5.3
            s.hausdorff_capped = capped;
        }
    }
    return finish_metrics(s, cc, options);
}

} // namespace specula::metrics
