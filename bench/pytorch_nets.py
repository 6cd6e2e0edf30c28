"""PyTorch reference definitions of the four networks cassi-nets implements:
MST-S / MST-L, HDNet and HSI-SDeCNN.

Written from the architecture description in ../shared/data/nets/README.md
(§1 inputs, §4 MST, §5 HDNet, §6 HSI-SDeCNN), not copied from the upstream
repositories. Module and parameter names follow the README, so
`load_state_dict(strict=True)` accepts the stored safetensors files.
Used by bench/pytorch_forward.py as the PyTorch side of the Rust-vs-PyTorch
timing; the outputs are checked there against the stored test vectors.
"""
import hashlib

import numpy as np
import torch
import torch.nn.functional as F
from torch import nn

# README §1: SHA-256 of the raw float32 data of the (unstored) network inputs.
H_SHA256 = "3b30543d830ef8b778738edcf3c2b4153d75da87985893878b27e7b308df1c0e"
PHI_SHA256 = "73479987fadb401f9c2ce200aa147d7d7c93528dd9443bd2e2d2d5310ac80ebe"


def sha256_of_data(a):
    return hashlib.sha256(np.ascontiguousarray(a).tobytes()).hexdigest()


def toolbox_inputs(y, mask, bands=28, step=2):
    """H (1,bands,256,256) and Phi (1,bands,256,256+(bands-1)*step) from the
    measurement y (1,256,310) and the mask (256,256), as README §1 says.
    The float32 order matters: divide by 28 first, then times 2 (y * (1/14)
    is not bit-identical)."""
    ys = (y[0] / np.float32(bands)) * np.float32(2)
    n = mask.shape[1]
    h = np.zeros((1, bands, mask.shape[0], n), np.float32)
    phi = np.zeros((1, bands, mask.shape[0], n + (bands - 1) * step), np.float32)
    for c in range(bands):
        h[0, c] = ys[:, step * c : step * c + n]
        phi[0, c, :, step * c : step * c + n] = mask
    return h, phi


# ---------------------------------------------------------------- MST (§4)


class MaskGuidance(nn.Module):
    """`mm`: m1 = conv1(mask); m2 = m1 * sigmoid(depth_conv(conv2(m1))) + m1,
    then shifted back to the h×h grid of the features (§4.3 step 2)."""

    def __init__(self, dim):
        super().__init__()
        self.conv1 = nn.Conv2d(dim, dim, 1, bias=True)
        self.conv2 = nn.Conv2d(dim, dim, 1, bias=True)
        self.depth_conv = nn.Conv2d(dim, dim, 5, padding=2, groups=dim, bias=True)

    def forward(self, mask):  # (B, C, h, W') channel-first
        m1 = self.conv1(mask)
        m2 = m1 * torch.sigmoid(self.depth_conv(self.conv2(m1))) + m1
        b, c, h, _ = m2.shape
        # Shift-back: band c moves left by floor(s*c), s = 2/D^2, D = 256/h.
        d = 256 // h
        offsets = torch.floor(torch.arange(c, dtype=torch.float64) * (2.0 / (d * d))).long()
        cols = torch.arange(h).view(1, h) + offsets.view(c, 1)  # (C, h)
        index = cols.view(1, c, 1, h).expand(b, c, h, h)
        return torch.gather(m2, 3, index)  # (B, C, h, h)


class MSMSA(nn.Module):
    """Mask-guided spectral-wise multi-head self-attention (§4.3), on
    channels-last x (B, h, w, C); attention is over channels (d×d per head)."""

    def __init__(self, dim, dim_head, heads):
        super().__init__()
        self.heads, self.dim_head = heads, dim_head
        self.to_q = nn.Linear(dim, dim_head * heads, bias=False)
        self.to_k = nn.Linear(dim, dim_head * heads, bias=False)
        self.to_v = nn.Linear(dim, dim_head * heads, bias=False)
        self.rescale = nn.Parameter(torch.ones(heads, 1, 1))
        self.proj = nn.Linear(dim_head * heads, dim, bias=True)
        self.pos_emb = nn.Sequential(
            nn.Conv2d(dim, dim, 3, padding=1, groups=dim, bias=False),
            nn.GELU(),
            nn.Conv2d(dim, dim, 3, padding=1, groups=dim, bias=False),
        )
        self.mm = MaskGuidance(dim)

    def forward(self, x, mask):
        b, h, w, c = x.shape
        x_flat = x.reshape(b, h * w, c)
        q_in, k_in, v_in = self.to_q(x_flat), self.to_k(x_flat), self.to_v(x_flat)
        # Only batch element 0's mask guidance is used, broadcast to the batch.
        emb = self.mm(mask)[0:1].permute(0, 2, 3, 1).reshape(1, h * w, c)

        def heads_first(t):  # (B, n, heads*d) -> (B, heads, d, n)
            return t.reshape(b, h * w, self.heads, self.dim_head).permute(0, 2, 3, 1)

        q, k, v = heads_first(q_in), heads_first(k_in), heads_first(v_in * emb)
        q = F.normalize(q, dim=-1, p=2)  # each row over the n positions
        k = F.normalize(k, dim=-1, p=2)
        attn = (k @ q.transpose(-2, -1)) * self.rescale  # (B, heads, d, d)
        attn = attn.softmax(dim=-1)
        out = (attn @ v).permute(0, 3, 1, 2).reshape(b, h * w, self.heads * self.dim_head)
        out_c = self.proj(out).view(b, h, w, c)
        # Positional branch on V before the mask multiplication.
        out_p = self.pos_emb(v_in.view(b, h, w, c).permute(0, 3, 1, 2)).permute(0, 2, 3, 1)
        return out_c + out_p


class FeedForward(nn.Module):
    """1×1 expand ×4, GELU, depthwise 3×3, GELU, 1×1 back; channels-last in/out."""

    def __init__(self, dim, mult=4):
        super().__init__()
        self.net = nn.Sequential(
            nn.Conv2d(dim, dim * mult, 1, bias=False),
            nn.GELU(),
            nn.Conv2d(dim * mult, dim * mult, 3, padding=1, groups=dim * mult, bias=False),
            nn.GELU(),
            nn.Conv2d(dim * mult, dim, 1, bias=False),
        )

    def forward(self, x):
        return self.net(x.permute(0, 3, 1, 2)).permute(0, 2, 3, 1)


class PreNorm(nn.Module):
    def __init__(self, dim, fn):
        super().__init__()
        self.norm = nn.LayerNorm(dim)
        self.fn = fn

    def forward(self, x):
        return self.fn(self.norm(x))


class MSAB(nn.Module):
    """n × (x = MSMSA(x, mask) + x; x = FFN(LayerNorm(x)) + x), channels-last
    inside; takes and returns (B, C, h, w)."""

    def __init__(self, dim, dim_head, heads, num_blocks):
        super().__init__()
        self.blocks = nn.ModuleList(
            nn.ModuleList([MSMSA(dim, dim_head, heads), PreNorm(dim, FeedForward(dim))])
            for _ in range(num_blocks)
        )

    def forward(self, x, mask):
        x = x.permute(0, 2, 3, 1)
        for attn, ff in self.blocks:
            x = attn(x, mask) + x
            x = ff(x) + x
        return x.permute(0, 3, 1, 2)


class MST(nn.Module):
    """U-shaped MST: MST(28, 2, [2,2,2]) is MST-S, MST(28, 2, [4,7,5]) MST-L.
    forward(x = H (B,28,256,256), mask = Phi (B,28,256,310))."""

    def __init__(self, dim=28, stage=2, num_blocks=(2, 2, 2)):
        super().__init__()
        self.stage = stage
        self.embedding = nn.Conv2d(28, dim, 3, padding=1, bias=False)
        self.encoder_layers = nn.ModuleList()
        d = dim
        for i in range(stage):
            self.encoder_layers.append(nn.ModuleList([
                MSAB(d, dim, d // dim, num_blocks[i]),
                nn.Conv2d(d, 2 * d, 4, stride=2, padding=1, bias=False),  # features down
                nn.Conv2d(d, 2 * d, 4, stride=2, padding=1, bias=False),  # mask down
            ]))
            d *= 2
        self.bottleneck = MSAB(d, dim, d // dim, num_blocks[-1])
        self.decoder_layers = nn.ModuleList()
        for i in range(stage):
            self.decoder_layers.append(nn.ModuleList([
                nn.ConvTranspose2d(d, d // 2, 2, stride=2, bias=True),
                nn.Conv2d(d, d // 2, 1, bias=False),  # fuse [up, skip]
                MSAB(d // 2, dim, (d // 2) // dim, num_blocks[stage - 1 - i]),
            ]))
            d //= 2
        self.mapping = nn.Conv2d(dim, 28, 3, padding=1, bias=False)

    def forward(self, x, mask):
        fea = F.leaky_relu(self.embedding(x), negative_slope=0.1)
        skips, masks = [], []
        for msab, fea_down, mask_down in self.encoder_layers:
            fea = msab(fea, mask)
            skips.append(fea)
            masks.append(mask)
            fea, mask = fea_down(fea), mask_down(mask)
        fea = self.bottleneck(fea, mask)
        for i, (up, fuse, msab) in enumerate(self.decoder_layers):
            fea = fuse(torch.cat([up(fea), skips[self.stage - 1 - i]], dim=1))
            fea = msab(fea, masks[self.stage - 1 - i])
        return self.mapping(fea) + x


def mst_s():
    return MST(28, 2, [2, 2, 2])


def mst_l():
    return MST(28, 2, [4, 7, 5])


# -------------------------------------------------------------- HDNet (§5)


def conv3(cin, cout):
    return nn.Conv2d(cin, cout, 3, padding=1, bias=True)


class ResBlock(nn.Module):
    def __init__(self, ch):
        super().__init__()
        self.body = nn.Sequential(conv3(ch, ch), nn.ReLU(inplace=True), conv3(ch, ch))

    def forward(self, x):
        return self.body(x) + x


class SDL(nn.Module):
    """Spatial-spectral attention (`body.16`): a channel gate G1 and a pixel
    gate G2, both multiplying x; output G1 + G2."""

    def __init__(self, ch=64, mid=32):
        super().__init__()
        self.conv_q_right = nn.Conv2d(ch, 1, 1, bias=False)
        self.conv_v_right = nn.Conv2d(ch, mid, 1, bias=False)
        self.conv_up = nn.Conv2d(mid, ch, 1, bias=False)
        self.conv_q_left = nn.Conv2d(ch, mid, 1, bias=False)
        self.conv_v_left = nn.Conv2d(ch, mid, 1, bias=False)

    def forward(self, x):
        b, _, h, w = x.shape
        n = h * w
        # G1: softmax(q) over pixels pools v to one vector -> per-channel gate.
        vr = self.conv_v_right(x).view(b, -1, n)
        p = self.conv_q_right(x).view(b, 1, n).softmax(dim=2)
        c = (vr @ p.transpose(1, 2)).unsqueeze(-1)  # (B, 32, 1, 1)
        g1 = x * torch.sigmoid(self.conv_up(c))
        # G2: mean-pooled query against per-pixel v -> per-pixel gate.
        row = self.conv_q_left(x).mean(dim=(2, 3)).unsqueeze(1)  # (B, 1, 32)
        th = self.conv_v_left(x).view(b, -1, n)
        t = (row @ th).softmax(dim=2)  # (B, 1, n)
        g2 = x * torch.sigmoid(t).view(b, 1, h, w)
        return g1 + g2


class DSC(nn.Module):
    def __init__(self, ch=16):
        super().__init__()
        self.conv_dws = nn.Conv2d(ch, ch, 1, groups=ch, bias=True)
        self.bn_dws = nn.BatchNorm2d(ch)
        self.conv_point = nn.Conv2d(ch, 1, 1, bias=True)
        self.bn_point = nn.BatchNorm2d(1)

    def forward(self, z):
        b, _, h, w = z.shape
        s = F.relu(self.bn_dws(self.conv_dws(z)))
        s = F.max_pool2d(s, 3, stride=1, padding=1)
        s = F.relu(self.bn_point(self.conv_point(s)))
        s = s.view(b, 1, h * w).softmax(dim=-1).view(b, 1, h, w)
        return s * z + z


class EFF(nn.Module):
    """`body.17`: four DSCs on consecutive 16-channel groups, concatenated."""

    def __init__(self, ch=64, groups=4):
        super().__init__()
        self.subspaces = nn.ModuleList(DSC(ch // groups) for _ in range(groups))

    def forward(self, x):
        parts = torch.chunk(x, len(self.subspaces), dim=1)
        return torch.cat([dsc(p) for dsc, p in zip(self.subspaces, parts)], dim=1)


class HDNet(nn.Module):
    def __init__(self, in_ch=28, out_ch=28, feats=64):
        super().__init__()
        self.head = nn.Sequential(conv3(in_ch, feats))
        body = [ResBlock(feats) for _ in range(16)] + [SDL(feats), EFF(feats)]
        body += [ResBlock(feats) for _ in range(15)] + [conv3(feats, feats)]
        self.body = nn.Sequential(*body)
        self.tail = nn.Sequential(conv3(feats, out_ch))

    def forward(self, x):
        f = self.head(x)
        return self.tail(self.body(f) + f)


# ---------------------------------------------------------- HSI-SDeCNN (§6)


class HSISDeCNN(nn.Module):
    """7-band stack + noise level -> denoised centre band, at half resolution
    after a pixel-unshuffle by 2."""

    def __init__(self, in_nc=7, out_nc=1, nc=128, nb=15):
        super().__init__()
        layers = [nn.Conv2d(in_nc * 4 + 1, nc, 3, padding=1), nn.ReLU(inplace=True)]
        for _ in range(nb - 2):
            layers += [nn.Conv2d(nc, nc, 3, padding=1), nn.ReLU(inplace=True)]
        layers.append(nn.Conv2d(nc, out_nc * 4, 3, padding=1))
        self.model = nn.Sequential(*layers)

    def forward(self, x, sigma):
        h, w = x.shape[-2:]
        if h % 2 or w % 2:  # odd sizes: replicate the last row/column
            x = F.pad(x, (0, w % 2, 0, h % 2), mode="replicate")
        u = F.pixel_unshuffle(x, 2)
        sigma_map = sigma.expand(-1, 1, u.shape[2], u.shape[3])
        t = self.model(torch.cat([u, sigma_map], dim=1))
        return F.pixel_shuffle(t, 2)[..., :h, :w]
