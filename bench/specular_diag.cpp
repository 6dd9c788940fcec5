// Diagnostic (not a test): residual samples against the true lobe on a synthetic scene.
//   specular_diag [preset] [size] [views] [lights] [light angle (deg)]
#include "diffuse_scene.h"
#include "specular/residuals.h"
#include "shared/lafortune.h"
#include "core/timer.h"

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <string>

using namespace specula;

static void stats(const char* name, const std::vector<ResidualSample>& s, const LafortuneRgb& truth,
                  const std::vector<ResidualSample>* ref = nullptr) {
    double se = 0, sw = 0, sb = 0, sf = 0;
    for (std::size_t i = 0; i < s.size(); ++i) {
        const glm::vec3 ft = shared::lafortune_eval_rgb(truth.cx, truth.cz, truth.n, glm::vec3(s[i].u), glm::vec3(s[i].v));
        const glm::vec3 base = ref ? (*ref)[i].f : ft;
        const double w = s[i].u.w;
        for (int c = 0; c < 3; ++c) {
            const double d = double(s[i].f[c]) - base[c];
            se += w * d * d;
            sb += w * d;
            sf += w * double(ft[c]) * ft[c];
        }
        sw += 3 * w;
    }
    std::printf("%-28s n=%zu  wrms err %.3e  wmean err %.3e  wrms truth %.3e\n", name, s.size(), std::sqrt(se / sw), sb / sw,
                std::sqrt(sf / sw));
}

static LafortuneFitRgb fit(const char* name, const std::vector<ResidualSample>& s) {
    Stopwatch sw;
    std::vector<LafortuneSample> all = to_lafortune_samples(s);
    if (all.size() > 200000) {
        const std::size_t stride = (all.size() + 199999) / 200000;
        std::vector<LafortuneSample> sub;
        for (std::size_t i = 0; i < all.size(); i += stride) sub.push_back(all[i]);
        all.swap(sub);
    }
    const LafortuneFitRgb f = fit_lafortune(all, {});
    std::printf("%-28s fit (%.2fs):", name, sw.seconds());
    for (int c = 0; c < 3; ++c)
        std::printf("  [%.4f %.4f %.2f %s]", f.channel[c].cx, f.channel[c].cz, f.channel[c].n, to_string(f.channel[c].status));
    std::printf("\n");
    return f;
}

static LafortuneRgb to_lobe(const LafortuneFitRgb& f) {
    LafortuneRgb l;
    for (int c = 0; c < 3; ++c) {
        l.cx[c] = float(f.channel[c].cx);
        l.cz[c] = float(f.channel[c].cz);
        l.n[c] = float(f.channel[c].n);
    }
    return l;
}

int main(int argc, char** argv) {
    test::SceneOptions so;
    so.preset = argc > 1 ? argv[1] : "can";
    so.size = argc > 2 ? std::atoi(argv[2]) : 128;
    so.views = argc > 3 ? std::atoi(argv[3]) : 6;
    so.lights = argc > 4 ? std::atoi(argv[4]) : 4;
    if (argc > 5) so.light_angles_deg = {std::atof(argv[5])};
    so.lambertian = false;
    so.format = synth::ImageFormat::Exr;
    Stopwatch sw;
    const test::DiffuseScene scene = test::make_scene(so);
    std::printf("scene %s %d px: %zu particles, %.2fs\n", so.preset.c_str(), so.size, scene.particles.particles.size(), sw.seconds());
    const LafortuneRgb truth = scene.preset.material.lobe;
    std::printf("truth: cx %.4f cz %.4f n %.2f\n", truth.cx.x, truth.cz.x, truth.n.x);
    const LambertInputs in = scene.inputs();
    sw = Stopwatch();
    const LambertOutputs solved = lambert_solve_cpu(in, {});
    std::printf("diffuse %.2fs\n", sw.seconds());
    LambertOutputs truth_alb = solved;
    double aerr = 0; std::size_t na = 0;
    for (std::size_t p = 0; p < truth_alb.particles.size(); ++p) {
        auto& r = truth_alb.particles[p];
        if (r.status & shared::kLambertOk) {
            const glm::vec3 d = glm::vec3(r.albedo_best) - scene.truth[p];
            aerr += glm::dot(d, d); ++na;
        }
        r.albedo_best = glm::vec4(scene.truth[p], r.albedo_best.w);
        r.albedo_robust = glm::vec4(scene.truth[p], r.albedo_robust.w);
    }
    std::printf("albedo rmse (best) %.4e over %zu\n", std::sqrt(aerr / (3.0 * na)), na);
    ResidualOptions all;
    all.max_albedo_spread = -1.0f;
    if (const char* j = std::getenv("DIAG_JOINT")) {
        const float spread = float(std::atof(j));
        ResidualOptions ro;
        ro.max_albedo_spread = spread;
        ro.drop_view_outliers = std::getenv("DIAG_KEEP_OUTLIERS") == nullptr;
        LambertOutputs cur = solved;
        for (int round = 0; round < 4; ++round) {
            const ResidualSamples rs = residual_samples_cpu(in, cur, ro);
            char name[64];
            std::snprintf(name, sizeof name, "round %d", round);
            stats(name, rs.samples, truth);
            const LafortuneFitRgb f = fit(name, rs.samples);
            {
                const LafortuneRgb fl = to_lobe(f);
                double ct = 0, cf = 0, cz0 = 0;
                for (const ResidualSample& q : rs.samples) {
                    const double w = q.u.w;
                    const double ft = shared::lafortune_eval(truth.cx.x, truth.cz.x, truth.n.x, glm::vec3(q.u), glm::vec3(q.v));
                    const double ff = shared::lafortune_eval(fl.cx.x, fl.cz.x, fl.n.x, glm::vec3(q.u), glm::vec3(q.v));
                    ct += w * (q.f.x - ft) * (q.f.x - ft);
                    cf += w * (q.f.x - ff) * (q.f.x - ff);
                    cz0 += w * q.f.x * q.f.x;
                }
                std::printf("  red cost: truth %.5e  fitted %.5e  zero lobe %.5e\n", ct, cf, cz0);
            }
            LambertOptions lo;
            lo.lobe = to_lobe(f);
            cur = lambert_solve_cpu(in, lo);
            double e2 = 0; std::size_t m = 0;
            for (std::size_t p = 0; p < cur.particles.size(); ++p)
                if (cur.particles[p].status & shared::kLambertOk) {
                    const glm::vec3 d = glm::vec3(cur.particles[p].albedo_best) - scene.truth[p];
                    e2 += glm::dot(d, d); ++m;
                }
            std::printf("  albedo rmse after round %d: %.4e\n", round, std::sqrt(e2 / (3.0 * m)));
        }
        return 0;
    }
    sw = Stopwatch();
    const ResidualSamples rs_s = residual_samples_cpu(in, solved, all);
    std::printf("residuals %.2fs\n", sw.seconds());
    const ResidualSamples rs_t = residual_samples_cpu(in, truth_alb, all);
    stats("truth-albedo vs lobe", rs_t.samples, truth);
    stats("solved-albedo vs lobe", rs_s.samples, truth);
    stats("solved vs truth-albedo", rs_s.samples, truth, &rs_t.samples);
    if (std::getenv("DIAG_ALL")) {
    fit("truth albedo", rs_t.samples);
    fit("solved albedo", rs_s.samples);
    }
    if (std::getenv("DIAG_ALL")) {
    const ResidualSamples rs_d = residual_samples_cpu(in, solved, {});
    stats("solved, default spread", rs_d.samples, truth);
    fit("solved, default spread", rs_d.samples);
    }
    // Only particles whose texture is flat around them (the image resolves their albedo).
    const std::vector<std::uint8_t> flat = test::flat_truth(scene, 2.0, 0.002f);
    LambertOutputs tf = truth_alb, sf = solved;
    std::size_t nflat = 0;
    for (std::size_t p = 0; p < flat.size(); ++p) {
        if (!flat[p]) { tf.particles[p].status = 0; sf.particles[p].status = 0; } else ++nflat;
    }
    std::printf("flat particles %zu\n", nflat);
    const ResidualSamples ft = residual_samples_cpu(in, tf, all);
    const ResidualSamples fs = residual_samples_cpu(in, sf, all);
    stats("flat truth-albedo vs lobe", ft.samples, truth);
    stats("flat solved vs lobe", fs.samples, truth);
    fit("flat truth albedo", ft.samples);
    fit("flat solved albedo", fs.samples);
    return 0;
}
