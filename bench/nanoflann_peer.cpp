// nanoflann_peer.cpp: nanoflann's KDTreeSingleIndexAdaptor behind the C interface of
// nanoflann_peer.h (see there). The dataset adaptor is the usual one nanoflann documents:
// a point count, a coordinate getter, and no precomputed bounding box.
#include "nanoflann_peer.h"

#include <cmath>
#include <limits>
#include <new>
#include <vector>

#include <nanoflann.hpp>

namespace {

struct Cloud {
    std::vector<float> xyz;
    size_t kdtree_get_point_count() const { return xyz.size() / 3; }
    float kdtree_get_pt(uint32_t i, size_t d) const { return xyz[3 * size_t(i) + d]; }
    template <class BBOX> bool kdtree_get_bbox(BBOX &) const { return false; }
};

using Metric = nanoflann::L2_Simple_Adaptor<float, Cloud, float, uint32_t>;
using Tree = nanoflann::KDTreeSingleIndexAdaptor<Metric, Cloud, 3, uint32_t>;

// The index array of a built tree (a public member of nanoflann's base class).
const std::vector<uint32_t> &tree_index(const Tree &t) { return t.vAcc; }

} // namespace

struct nf_peer {
    Cloud cloud;
    Tree *tree = nullptr;
};

extern "C" nf_peer *nf_build(const float *xyz, size_t n, unsigned leaf, int tree_order,
                             double (*now)(void), double *build_s) {
    nf_peer *p = new (std::nothrow) nf_peer;
    if (!p) return nullptr;
    try {
        p->cloud.xyz.assign(xyz, xyz + 3 * n);
        double t0 = now();
        p->tree = new Tree(3, p->cloud, nanoflann::KDTreeSingleIndexAdaptorParams(leaf));
        *build_s = now() - t0;
        if (tree_order) {
            const std::vector<uint32_t> &ord = tree_index(*p->tree);
            std::vector<float> re(3 * n);
            for (size_t i = 0; i < n; i++)
                for (size_t d = 0; d < 3; d++) re[3 * i + d] = xyz[3 * size_t(ord[i]) + d];
            delete p->tree;
            p->tree = nullptr;
            p->cloud.xyz.swap(re);
            p->tree = new Tree(3, p->cloud, nanoflann::KDTreeSingleIndexAdaptorParams(leaf));
        }
    } catch (...) {
        delete p->tree;
        delete p;
        return nullptr;
    }
    return p;
}

extern "C" void nf_free(nf_peer *p) {
    if (!p) return;
    delete p->tree;
    delete p;
}

extern "C" unsigned nf_knn(const nf_peer *p, const float q[3], unsigned k, float r2,
                           uint32_t *idx, float *dist2) {
    if (k == 0) return 0;
    nanoflann::KNNResultSet<float, uint32_t, unsigned> rs(k);
    rs.init(idx, dist2);
    if (!std::isinf(r2)) dist2[k - 1] = r2; // the worst distance the search starts from
    p->tree->findNeighbors(rs, q, nanoflann::SearchParams());
    return rs.size();
}

extern "C" const float *nf_pos(const nf_peer *p, uint32_t i) {
    return &p->cloud.xyz[3 * size_t(i)];
}

extern "C" size_t nf_index_bytes(const nf_peer *p) { return p->tree->usedMemory(*p->tree); }

extern "C" unsigned nf_version(void) { return NANOFLANN_VERSION; }
