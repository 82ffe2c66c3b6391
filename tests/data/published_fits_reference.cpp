// Reference values (float_t is float in dj_brdf: a pair exactly at the mirror direction is left out, where
// float rounding of the half vector moves a sharp peak by up to 17 %) of dj_brdf's sgd and abc at fixed direction pairs (tests/data/published_fits_reference.json).
#define DJ_BRDF_IMPLEMENTATION 1
#include "dj_brdf.h"
#include <cstdio>
#include <cmath>
int main() {
    const char *names[] = {"white-paint", "nickel", "specular-black-phenolic", "blue-fabric", "alum-bronze"};
    // (theta_i, phi_i, theta_o, phi_o) in degrees
    const double dirs[][4] = {{0,0,0,0},{45,20,10,200},{60,0,60,180},{70,90,20,10},{5,0,15,180},{80,0,80,180},{30,0,31,182}};
    printf("[\n");
    bool first = true;
    for (const char *name : names) {
        djb::sgd s(name); djb::abc a(name);
        for (auto &d : dirs) {
            double ti = d[0]*M_PI/180, pi_ = d[1]*M_PI/180, to = d[2]*M_PI/180, po = d[3]*M_PI/180;
            djb::vec3 i(sin(ti)*cos(pi_), sin(ti)*sin(pi_), cos(ti)), o(sin(to)*cos(po), sin(to)*sin(po), cos(to));
            djb::vec3 fs = s.eval(i, o), fa = a.eval(i, o);
            printf("%s{\"material\": \"%s\", \"wi\": [%.17g, %.17g, %.17g], \"wo\": [%.17g, %.17g, %.17g], \"sgd\": [%.17g, %.17g, %.17g], \"abc\": [%.17g, %.17g, %.17g]}\n",
                   first ? " " : ",", name, (double)i.x, (double)i.y, (double)i.z, (double)o.x, (double)o.y, (double)o.z,
                   (double)fs.x, (double)fs.y, (double)fs.z, (double)fa.x, (double)fa.y, (double)fa.z);
            first = false;
        }
    }
    printf("]\n");
}
