#pragma once
// Vertex + fragment pipelines from SPIR-V embedded at build time
// (build/spirv/<stage>/<name>.vert.h defines <stage>_<name>_vert[]).
//
// Conventions (the raster passes' needs, kept small):
// - Vertices come either from one interleaved vertex buffer (binding 0, per-vertex
//   rate, `vertex_stride` and `vertex_attributes` in the desc; the buffer is an
//   ordinary gpu::Buffer, bound with bind_vertex_buffer) or, with no attributes, are
//   pulled by the vertex shader from storage buffers by gl_VertexIndex.
// - One descriptor set (set 0) whose bindings are listed in the desc, in order;
//   a DescriptorSet owns one set of that layout and is written once.
// - Viewport and scissor are dynamic state (render_target.h sets them).
// - The pipeline is built against a render pass; any compatible render pass
//   (same attachment formats and sample counts) may be used with it.
#include "gpu/buffer.h"
#include "gpu/context.h"
#include "gpu/image.h"

#include <cstdint>
#include <span>
#include <string>
#include <vector>

namespace specula::gpu {

struct DescriptorBinding {
    // STORAGE_BUFFER, COMBINED_IMAGE_SAMPLER or INPUT_ATTACHMENT (fragment stage only)
    VkDescriptorType type = VK_DESCRIPTOR_TYPE_STORAGE_BUFFER;
    VkShaderStageFlags stages = VK_SHADER_STAGE_VERTEX_BIT | VK_SHADER_STAGE_FRAGMENT_BIT;
};

enum class BlendMode {
    None,     // the fragment replaces the attachment
    Additive, // colour: dst + src; alpha: dst kept (so alpha can carry coverage from an earlier pass)
};

struct GraphicsPipelineDesc {
    std::string name;
    std::span<const uint32_t> vertex_spirv;
    std::span<const uint32_t> fragment_spirv; // empty: depth only (a render pass with no colour attachment)
    std::vector<DescriptorBinding> bindings; // set 0, binding i = bindings[i]
    uint32_t push_constant_bytes = 0;        // vertex + fragment stages, offset 0, <= 128
    VkRenderPass render_pass = VK_NULL_HANDLE;
    uint32_t subpass = 0;
    uint32_t color_attachments = 1; // of the subpass (1 to 4), all blended alike; none when depth only
    bool depth_test = true;
    bool depth_write = true;
    VkCompareOp depth_compare = VK_COMPARE_OP_GREATER; // reversed-Z: nearer is larger
    BlendMode blend = BlendMode::None;
    VkCullModeFlags cull_mode = VK_CULL_MODE_NONE;
    VkFrontFace front_face = VK_FRONT_FACE_COUNTER_CLOCKWISE;
    float depth_bias_constant = 0.0f; // rasterizer depth bias (both zero: disabled)
    float depth_bias_slope = 0.0f;
    // Vertex input binding 0 (empty: none, the shader pulls its vertices). Fixed-function
    // fetch is the faster path on lavapipe, whose vertex stage runs on one thread.
    uint32_t vertex_stride = 0;
    std::vector<VkVertexInputAttributeDescription> vertex_attributes; // .binding must be 0
    // Specialization constants of the fragment shader: constant_id i takes fragment_constants[i]
    // (32-bit). The driver compiles the branches they decide away; lavapipe runs both sides of a
    // branch on a uniform value, texture lookups included.
    std::vector<uint32_t> fragment_constants;
};

/// Binds `buffer` as vertex input binding 0 of the bound pipeline (offset 0).
void bind_vertex_buffer(VkCommandBuffer cmd, const Buffer& buffer);

class GraphicsPipeline {
public:
    GraphicsPipeline(Context& ctx, const GraphicsPipelineDesc& desc);
    GraphicsPipeline(GraphicsPipeline&&) noexcept = default;
    GraphicsPipeline& operator=(GraphicsPipeline&&) noexcept = default;
    GraphicsPipeline(const GraphicsPipeline&) = delete;
    GraphicsPipeline& operator=(const GraphicsPipeline&) = delete;

    [[nodiscard]] VkPipeline pipeline() const noexcept { return m_pipeline.get(); }
    [[nodiscard]] VkPipelineLayout layout() const noexcept { return m_layout.get(); }
    [[nodiscard]] VkDescriptorSetLayout set_layout() const noexcept { return m_set_layout.get(); }
    [[nodiscard]] const std::vector<DescriptorBinding>& bindings() const noexcept { return m_bindings; }
    [[nodiscard]] const std::string& name() const noexcept { return m_name; }
    [[nodiscard]] uint32_t push_constant_bytes() const noexcept { return m_push_constant_bytes; }

private:
    std::string m_name;
    std::vector<DescriptorBinding> m_bindings;
    uint32_t m_push_constant_bytes = 0;
    UniqueDescriptorSetLayout m_set_layout;
    UniquePipelineLayout m_layout;
    UniquePipeline m_pipeline;
};

/// One descriptor set (with its own pool) of a pipeline's set-0 layout. Write every
/// binding before the first draw; a write must not happen while a draw using the set
/// is in flight (Sequence::submit_and_wait returns after the work finished).
class DescriptorSet {
public:
    DescriptorSet(Context& ctx, const GraphicsPipeline& pipeline);
    DescriptorSet(DescriptorSet&&) noexcept = default;
    DescriptorSet& operator=(DescriptorSet&&) noexcept = default;
    DescriptorSet(const DescriptorSet&) = delete;
    DescriptorSet& operator=(const DescriptorSet&) = delete;

    void write_buffer(uint32_t binding, const Buffer& buffer);
    /// The image must be in SHADER_READ_ONLY_OPTIMAL when it is sampled (Image::upload leaves it so).
    void write_image(uint32_t binding, const Image& image, VkSampler sampler);
    /// An input attachment read by subpassLoad (the image in SHADER_READ_ONLY_OPTIMAL in that subpass).
    void write_input_attachment(uint32_t binding, const Image& image);

    [[nodiscard]] VkDescriptorSet get() const noexcept { return m_set; }

private:
    void check_binding(uint32_t binding, VkDescriptorType type) const;

    Context* m_ctx;
    std::string m_name;
    std::vector<DescriptorBinding> m_bindings;
    UniqueDescriptorPool m_pool;
    VkDescriptorSet m_set = VK_NULL_HANDLE; // freed with the pool
};

} // namespace specula::gpu
