"""Yarn-level rendering: frame records -> centripetal Catmull-Rom tubes -> headless OpenGL -> PNG / MP4.

Modules, each with one job (docs/rendering.md has the whole picture):
- context: the one GL context factory (EGL, llvmpipe-friendly), GL error checks
- yarns: yarn centre-line pieces of a frame (base-level and yarn-level crossings, cuts)
- spline: centripetal Catmull-Rom sampling; tube: rotation-minimising frames, tube sweep, fade alpha
- lod: level of detail from on-screen yarn size; geometry: the per-frame geometry stage
- wireframe, bodies, camera, color: spring lines, rigid bodies, view matrices, sRGB
- renderer: MSAA drawing, sorted transparency, resolve and read-back
- encode: atomic PNG and video (H.264 MP4, ProRes 4444 .mov); png16: 16-bit PNG; exr: OpenEXR frames
  (linear premultiplied RGBA + Z)
- options, job, sequence, command: `fraytool render`; bench: `fraytool bench --render`
Rendering reads only frame records and the saved topology; the simulation never imports it.
"""
