#include "scene/medium_presets.h"

#include <array>

namespace theia {

namespace {

// Sources of the measured coefficients (sigma_s', sigma_a in mm^-1, RGB):
// - Jensen, Marschner, Levoy, Hanrahan, "A Practical Model for Subsurface
//   Light Transport", SIGGRAPH 2001, its table of measured media (Apple ... Wholemilk);
// - Narasimhan, Gupta, Donner, Ramamoorthi, Nayar, Jensen, "Acquiring
//   Scattering Properties of Participating Media by Dilution", SIGGRAPH 2006,
//   its table of measured media (Lowfat Milk ... Pacific Ocean Surface Water).
// Names and values as pbrt-v4's media.cpp lists them (its data reference).
const std::array kPresets = {
    // clang-format off
    MediumPreset{"Apple", RGB(2.29f, 2.39f, 1.97f), RGB(0.0030f, 0.0034f, 0.046f)},
    MediumPreset{"Chicken1", RGB(0.15f, 0.21f, 0.38f), RGB(0.015f, 0.077f, 0.19f)},
    MediumPreset{"Chicken2", RGB(0.19f, 0.25f, 0.32f), RGB(0.018f, 0.088f, 0.20f)},
    MediumPreset{"Cream", RGB(7.38f, 5.47f, 3.15f), RGB(0.0002f, 0.0028f, 0.0163f)},
    MediumPreset{"Ketchup", RGB(0.18f, 0.07f, 0.03f), RGB(0.061f, 0.97f, 1.45f)},
    MediumPreset{"Marble", RGB(2.19f, 2.62f, 3.00f), RGB(0.0021f, 0.0041f, 0.0071f)},
    MediumPreset{"Potato", RGB(0.68f, 0.70f, 0.55f), RGB(0.0024f, 0.0090f, 0.12f)},
    MediumPreset{"Skimmilk", RGB(0.70f, 1.22f, 1.90f), RGB(0.0014f, 0.0025f, 0.0142f)},
    MediumPreset{"Skin1", RGB(0.74f, 0.88f, 1.01f), RGB(0.032f, 0.17f, 0.48f)},
    MediumPreset{"Skin2", RGB(1.09f, 1.59f, 1.79f), RGB(0.013f, 0.070f, 0.145f)},
    MediumPreset{"Spectralon", RGB(11.6f, 20.4f, 14.9f), RGB(0.00f, 0.00f, 0.00f)},
    MediumPreset{"Wholemilk", RGB(2.55f, 3.21f, 3.77f), RGB(0.0011f, 0.0024f, 0.014f)},
    MediumPreset{"Lowfat Milk", RGB(0.89187f, 1.5136f, 2.532f), RGB(0.002875f, 0.00575f, 0.0115f)},
    MediumPreset{"Reduced Milk", RGB(2.4858f, 3.1669f, 4.5214f), RGB(0.0025556f, 0.0051111f, 0.012778f)},
    MediumPreset{"Regular Milk", RGB(4.5513f, 5.8294f, 7.136f), RGB(0.0015333f, 0.0046f, 0.019933f)},
    MediumPreset{"Espresso", RGB(0.72378f, 0.84557f, 1.0247f), RGB(4.7984f, 6.5751f, 8.8493f)},
    MediumPreset{"Mint Mocha Coffee", RGB(0.31602f, 0.38538f, 0.48131f), RGB(3.772f, 5.8228f, 7.82f)},
    MediumPreset{"Lowfat Soy Milk", RGB(0.30576f, 0.34233f, 0.61664f), RGB(0.0014375f, 0.0071875f, 0.035937f)},
    MediumPreset{"Regular Soy Milk", RGB(0.59223f, 0.73866f, 1.4693f), RGB(0.0019167f, 0.0095833f, 0.065167f)},
    MediumPreset{"Lowfat Chocolate Milk", RGB(0.64925f, 0.83916f, 1.1057f), RGB(0.0115f, 0.0368f, 0.1564f)},
    MediumPreset{"Regular Chocolate Milk", RGB(1.4585f, 2.1289f, 2.9527f), RGB(0.010063f, 0.043125f, 0.14375f)},
    MediumPreset{"Coke", RGB(8.9053e-05f, 8.372e-05f, 0.0f), RGB(0.10014f, 0.16503f, 0.2468f)},
    MediumPreset{"Pepsi", RGB(6.1697e-05f, 4.2564e-05f, 0.0f), RGB(0.091641f, 0.14158f, 0.20729f)},
    MediumPreset{"Sprite", RGB(6.0306e-06f, 6.4139e-06f, 6.5504e-06f), RGB(0.001886f, 0.0018308f, 0.0020025f)},
    MediumPreset{"Gatorade", RGB(0.0024574f, 0.003007f, 0.0037325f), RGB(0.024794f, 0.019289f, 0.008878f)},
    MediumPreset{"Chardonnay", RGB(1.7982e-05f, 1.3758e-05f, 1.2023e-05f), RGB(0.010782f, 0.011855f, 0.023997f)},
    MediumPreset{"White Zinfandel", RGB(1.7501e-05f, 1.9069e-05f, 1.288e-05f), RGB(0.012072f, 0.016184f, 0.019843f)},
    MediumPreset{"Merlot", RGB(2.1129e-05f, 0.0f, 0.0f), RGB(0.11632f, 0.25191f, 0.29434f)},
    MediumPreset{"Budweiser Beer", RGB(2.4356e-05f, 2.4079e-05f, 1.0564e-05f), RGB(0.011492f, 0.024911f, 0.057786f)},
    MediumPreset{"Coors Light Beer", RGB(5.0922e-05f, 4.301e-05f, 0.0f), RGB(0.006164f, 0.013984f, 0.034983f)},
    MediumPreset{"Clorox", RGB(0.0024035f, 0.0031373f, 0.003991f), RGB(0.0033542f, 0.014892f, 0.026297f)},
    MediumPreset{"Apple Juice", RGB(0.00013612f, 0.00015836f, 0.000227f), RGB(0.012957f, 0.023741f, 0.052184f)},
    MediumPreset{"Cranberry Juice", RGB(0.00010402f, 0.00011646f, 7.8139e-05f), RGB(0.039437f, 0.094223f, 0.12426f)},
    MediumPreset{"Grape Juice", RGB(5.382e-05f, 0.0f, 0.0f), RGB(0.10404f, 0.23958f, 0.29325f)},
    MediumPreset{"Ruby Grapefruit Juice", RGB(0.011002f, 0.010927f, 0.011036f), RGB(0.085867f, 0.18314f, 0.25262f)},
    MediumPreset{"White Grapefruit Juice", RGB(0.22826f, 0.23998f, 0.32748f), RGB(0.0138f, 0.018831f, 0.056781f)},
    MediumPreset{"Shampoo", RGB(0.0007176f, 0.0008303f, 0.0009016f), RGB(0.014107f, 0.045693f, 0.061717f)},
    MediumPreset{"Strawberry Shampoo", RGB(0.00015671f, 0.00015947f, 1.518e-05f), RGB(0.01449f, 0.05796f, 0.075823f)},
    MediumPreset{"Head & Shoulders Shampoo", RGB(0.023805f, 0.028804f, 0.034306f), RGB(0.084621f, 0.15688f, 0.20365f)},
    MediumPreset{"Lemon Tea Powder", RGB(0.040224f, 0.045264f, 0.051081f), RGB(2.4288f, 4.5757f, 7.2127f)},
    MediumPreset{"Orange Powder", RGB(0.00015617f, 0.00017482f, 0.0001762f), RGB(0.001449f, 0.003441f, 0.007863f)},
    MediumPreset{"Pink Lemonade Powder", RGB(0.00012103f, 0.00013073f, 0.00012528f), RGB(0.001165f, 0.002366f, 0.003195f)},
    MediumPreset{"Cappuccino Powder", RGB(1.8436f, 2.5851f, 2.1662f), RGB(35.844f, 49.547f, 61.084f)},
    MediumPreset{"Salt Powder", RGB(0.027333f, 0.032451f, 0.031979f), RGB(0.28415f, 0.3257f, 0.34148f)},
    MediumPreset{"Sugar Powder", RGB(0.00022272f, 0.00025513f, 0.000271f), RGB(0.012638f, 0.031051f, 0.050124f)},
    MediumPreset{"Suisse Mocha Powder", RGB(2.7979f, 3.5452f, 4.3365f), RGB(17.502f, 27.004f, 35.433f)},
    MediumPreset{"Pacific Ocean Surface Water", RGB(0.0001764f, 0.00032095f, 0.00019617f), RGB(0.031845f, 0.031324f, 0.030147f)},
    // clang-format on
};

}  // namespace

const MediumPreset* find_medium_preset(std::string_view name) {
  for (const MediumPreset& p : kPresets)
    if (p.name == name) return &p;
  return nullptr;
}

std::string medium_preset_names() {
  std::string names;
  for (const MediumPreset& p : kPresets) {
    if (!names.empty()) names += ", ";
    names.append(1, '"').append(p.name).append(1, '"');
  }
  return names;
}

}  // namespace theia
