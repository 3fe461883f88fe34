#pragma once
/// Fixed-size Eigen types used across LTLO-SLAM (STYLE.md section 6). Estimation is in double.
#include <Eigen/Core>
#include <Eigen/Geometry>

namespace ltlo {

using Vec2 = Eigen::Vector2d;
using Vec3 = Eigen::Vector3d;
using Vec4 = Eigen::Vector4d;
using Vec6 = Eigen::Matrix<double, 6, 1>;
using Vec7 = Eigen::Matrix<double, 7, 1>;
using Vec9 = Eigen::Matrix<double, 9, 1>;
using Vec15 = Eigen::Matrix<double, 15, 1>;
using VecX = Eigen::VectorXd;

using Mat2 = Eigen::Matrix2d;
using Mat3 = Eigen::Matrix3d;
using Mat4 = Eigen::Matrix4d;
using Mat6 = Eigen::Matrix<double, 6, 6>;
using Mat7 = Eigen::Matrix<double, 7, 7>;
using Mat9 = Eigen::Matrix<double, 9, 9>;
using Mat15 = Eigen::Matrix<double, 15, 15>;
using Mat23 = Eigen::Matrix<double, 2, 3>;
using Mat36 = Eigen::Matrix<double, 3, 6>;
using MatX = Eigen::MatrixXd;

using Quat = Eigen::Quaterniond;

}  // namespace ltlo
