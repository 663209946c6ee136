/* scene_ports.c: the photon ports of a JSON scene (scene_load_internal.h; port.h is what a
 * port is, data/scenes/README.md the format):
 *   "ports": [{"type": "quad", "corner": [x, y, z], "edge1": [..], "edge2": [..]},
 *             {"type": "disc", "center": [..], "normal": [..], "radius": r}],
 *   "port_fraction": 0.5,
 *   "find_ports": true   (false: the plan does not look for ports of its own, ports.h)
 * Every field is checked, with the JSON path of the mistake in the message.
 */
#include "load/scene_load_internal.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "photonmap/common.h"

#define PORTS_MAX 256 /* ports of one scene: each photon's density is a sum over them */

static int load_port(port *out, const cJSON *o, const char *P, json_err *e) {
    if (!cJSON_IsObject(o))
        return json_fail(e, PM_EINVAL, "%s: expected an object, got %s", P, json_type_name(o));
    const char *type;
    TRY(json_string(o, P, "type", 1, &type, e));
    if (strcmp(type, "quad") == 0) {
        KEYS(o, P, "a quad port", "type", "corner", "edge1", "edge2");
        vec3 c, e1, e2;
        TRY(json_vec3(o, P, "corner", 1, &c, e));
        TRY(sl_check_point(c, P, "corner", e));
        TRY(json_vec3(o, P, "edge1", 1, &e1, e));
        TRY(sl_check_point(e1, P, "edge1", e));
        TRY(json_vec3(o, P, "edge2", 1, &e2, e));
        TRY(sl_check_point(e2, P, "edge2", e));
        double l1 = v3_len(e1), l2 = v3_len(e2), cr = v3_len(v3_cross(e1, e2));
        if (!(l1 > 0)) return json_fail(e, PM_EINVAL, "%s.edge1: must not be zero", P);
        if (!(l2 > 0)) return json_fail(e, PM_EINVAL, "%s.edge2: must not be zero", P);
        if (!(cr > 1e-9 * l1 * l2) || !isfinite(cr))
            return json_fail(e, PM_EINVAL, "%s: edge1 and edge2 are parallel (the quad has no area)", P);
        *out = port_quad(c, e1, e2);
    } else if (strcmp(type, "disc") == 0) {
        KEYS(o, P, "a disc port", "type", "center", "normal", "radius");
        vec3 c, n;
        double r;
        TRY(json_vec3(o, P, "center", 1, &c, e));
        TRY(sl_check_point(c, P, "center", e));
        TRY(json_vec3(o, P, "normal", 1, &n, e));
        TRY(sl_check_point(n, P, "normal", e));
        if (!(v3_len(n) > 0)) return json_fail(e, PM_EINVAL, "%s.normal: must not be zero", P);
        TRY(json_number(o, P, "radius", 1, &r, e));
        if (!(r > 0 && r <= SCENE_LENGTH_MAX))
            return json_fail(e, PM_EINVAL, "%s.radius: must be positive and at most %g, got %g", P,
                             SCENE_LENGTH_MAX, r);
        *out = port_disc(c, n, r);
    } else {
        return json_fail(e, PM_EINVAL, "%s.type: unknown port type \"%s\" (quad, disc)", P, type);
    }
    return 0;
}

int sl_load_ports(scene *s, const cJSON *root, json_err *e) {
    const cJSON *ps;
    TRY(json_array(root, "$", "ports", 0, &ps, e));
    s->port_fraction = 0.5;
    s->find_ports = 1;
    if (json_get(root, "find_ports")) {
        const cJSON *f = json_get(root, "find_ports");
        if (!cJSON_IsBool(f))
            return json_fail(e, PM_EINVAL, "$.find_ports: expected true or false, got %s", json_type_name(f));
        s->find_ports = cJSON_IsTrue(f);
    }
    if (json_get(root, "port_fraction")) {
        if (!ps) return json_fail(e, PM_EINVAL, "$.port_fraction: given without $.ports");
        TRY(json_number(root, "$", "port_fraction", 1, &s->port_fraction, e));
        if (!(s->port_fraction >= 0 && s->port_fraction < 1))
            return json_fail(e, PM_EINVAL, "$.port_fraction: must be at least 0 and below 1 (the rest of the "
                             "photons are emitted as without ports, which keeps the estimate unbiased), got %g",
                             s->port_fraction);
    }
    int n = ps ? cJSON_GetArraySize(ps) : 0;
    if (ps && n == 0) return json_fail(e, PM_EINVAL, "$.ports: empty (leave it out for no ports)");
    if (n > PORTS_MAX) return json_fail(e, PM_EINVAL, "$.ports: %d ports, at most %d are supported", n, PORTS_MAX);
    if (n == 0) return 0;
    s->ports = calloc((size_t)n, sizeof *s->ports);
    if (!s->ports) return json_fail(e, PM_ENOMEM, "out of memory");
    int i = 0;
    char p[P_MAX];
    for (const cJSON *it = ps->child; it; it = it->next, i++) {
        json_path_index(p, sizeof p, "$.ports", i);
        TRY(load_port(&s->ports[i], it, p, e));
        s->nports = i + 1;
    }
    return 0;
}
