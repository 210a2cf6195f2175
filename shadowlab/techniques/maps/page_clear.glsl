// Clears one page of a depth atlas: drawn over the page's viewport with the depth test set to
// pass always, every fragment writes u_depth. UE5's virtual shadow maps clear only the pages they
// render (the lab's state model keeps the scissor test off, so glClear cannot do one page).
#include "fullscreen.glsl"

#ifdef FRAGMENT_SHADER
uniform float u_depth;                   // the window depth written (the map's "nothing drawn")
void main() {
    gl_FragDepth = u_depth;
}
#endif
